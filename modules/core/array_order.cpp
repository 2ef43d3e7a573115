#include "core/array_order.h"

#include <algorithm>
#include <cmath>

namespace ms {

AxisReorder canonical_reorder(const Geometry& g) {
  // Column c of the direction matrix is axis c's unit vector in LPS.
  auto comp = [&](int axis, int lps) { return g.direction[static_cast<std::size_t>(3 * lps + axis)]; };
  std::array<int, 3> perm{0, 1, 2}, best = perm;
  double best_sum = -1;
  do {  // perm[a] = the old axis that becomes new axis a (L, P, S)
    double sum = 0;
    for (int a = 0; a < 3; ++a) sum += std::abs(comp(perm[a], a));
    if (sum > best_sum + 1e-12) best_sum = sum, best = perm;
  } while (std::next_permutation(perm.begin(), perm.end()));
  AxisReorder r;
  r.from = best;
  for (int a = 0; a < 3; ++a) r.flip[a] = comp(best[a], a) < 0;
  return r;
}

AxisReorder inverse(const AxisReorder& r) {
  AxisReorder back;
  for (int a = 0; a < 3; ++a) {
    const auto b = static_cast<std::size_t>(r.from[static_cast<std::size_t>(a)]);
    back.from[b] = a;
    back.flip[b] = r.flip[static_cast<std::size_t>(a)];
  }
  return back;
}

Geometry reordered(const Geometry& g, const AxisReorder& r) {
  Geometry n = g;
  std::array<double, 3> first{};  // old index of the new grid's first voxel
  for (int a = 0; a < 3; ++a) {
    const auto b = static_cast<std::size_t>(r.from[a]);
    n.size[a] = g.size[b];
    n.spacing[a] = g.spacing[b];
    for (int row = 0; row < 3; ++row)
      n.direction[static_cast<std::size_t>(3 * row + a)] = (r.flip[a] ? -1.0 : 1.0) * g.direction[3 * static_cast<std::size_t>(row) + b];
    first[b] = r.flip[a] ? static_cast<double>(g.size[b]) - 1.0 : 0.0;
  }
  n.origin = g.index_to_lps(first[0], first[1], first[2]);
  return n;
}

}  // namespace ms
