// One canonical array order for every grid read (docs/ingest.md, "Array
// order"): the same scan stored with its rows, columns or slices in another
// order (DICOM, NIfTI in RAS or LAS, NRRD, MHA) holds the same voxels at the
// same world positions, but meshing and decimation visit voxels in array
// order. So ingest brings every grid to the order whose axes point, as near
// as the grid allows, to patient left (i), posterior (j) and superior (k):
// the axes are permuted (the one nearest each of L, P, S) and flipped where
// they point the other way. Positions, spacing and values are unchanged; the
// direction matrix becomes the one nearest the identity.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "core/types.h"

namespace ms {

// New axis a takes old axis from[a], reversed when flip[a].
struct AxisReorder {
  std::array<int, 3> from{0, 1, 2};
  std::array<bool, 3> flip{false, false, false};
  bool identity() const { return from == std::array<int, 3>{0, 1, 2} && !flip[0] && !flip[1] && !flip[2]; }
};

// The permutation (of the 6) that maximises the summed |L, P, S component| of
// the axes it assigns, and the flips that make those components positive.
AxisReorder canonical_reorder(const Geometry& g);

// The grid after the reorder: same voxel positions, new index order.
Geometry reordered(const Geometry& g, const AxisReorder& r);

// The reorder that undoes r: reordered(reordered(g, r), inverse(r)) is g.
AxisReorder inverse(const AxisReorder& r);

// Values of grid g (x fastest) in the reordered grid's order.
template <class T>
std::vector<T> reordered_values(const std::vector<T>& v, const Geometry& g, const AxisReorder& r) {
  if (r.identity()) return v;
  const Geometry n = reordered(g, r);
  std::vector<T> out(v.size());
  // Old linear index = sum over new axes a of (old index along from[a]) * stride of from[a].
  const std::array<std::size_t, 3> old_stride{1, g.size[0], g.size[0] * g.size[1]};
  std::array<std::ptrdiff_t, 3> step{}, start{};
  for (int a = 0; a < 3; ++a) {
    const std::size_t s = old_stride[static_cast<std::size_t>(r.from[a])];
    step[a] = r.flip[a] ? -static_cast<std::ptrdiff_t>(s) : static_cast<std::ptrdiff_t>(s);
    start[a] = r.flip[a] ? static_cast<std::ptrdiff_t>((n.size[a] - 1) * s) : 0;
  }
  const long nk = static_cast<long>(n.size[2]);
#pragma omp parallel for schedule(static)
  for (long k = 0; k < nk; ++k)
    for (std::size_t j = 0; j < n.size[1]; ++j) {
      std::ptrdiff_t at = start[0] + start[1] + start[2] + static_cast<std::ptrdiff_t>(j) * step[1] + k * step[2];
      T* dst = out.data() + n.linear(0, j, static_cast<std::size_t>(k));
      for (std::size_t i = 0; i < n.size[0]; ++i, at += step[0]) dst[i] = v[static_cast<std::size_t>(at)];
    }
  return out;
}

}  // namespace ms
