#include "segmentation/cranium.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace ms::segmentation {

Cranium cranium_mask(const Volume& ct, const Mask& mandible, const CraniumOptions& opt) {
  const Geometry& g = ct.geom;
  std::size_t b[3];
  Geometry cg = g;
  for (int a = 0; a < 3; ++a) {
    b[a] = static_cast<std::size_t>(std::max(1.0, std::round(opt.voxel_mm / g.spacing[a])));
    cg.size[a] = (g.size[a] + b[a] - 1) / b[a];
    cg.spacing[a] = g.spacing[a] * static_cast<double>(b[a]);
  }
  // Coarse voxel centre = centre of its block.
  cg.origin = g.index_to_lps(0.5 * static_cast<double>(b[0] - 1), 0.5 * static_cast<double>(b[1] - 1),
                             0.5 * static_cast<double>(b[2] - 1));
  const std::size_t n = cg.voxel_count();
  std::vector<double> sum(n, 0.0);
  std::vector<std::uint32_t> cnt(n, 0);
  std::vector<std::uint8_t> near_mandible(n, 0);
  const bool has_mandible = mandible.geom.same_grid(g) && mandible.data.size() == g.voxel_count();
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        const std::size_t src = g.linear(i, j, k), dst = cg.linear(i / b[0], j / b[1], k / b[2]);
        sum[dst] += ct.hu[src];
        ++cnt[dst];
        if (has_mandible && mandible.data[src]) near_mandible[dst] = 1;
      }
  // Dilate the mandible's blocks by the exclusion distance (box, per axis).
  int r[3];
  for (int a = 0; a < 3; ++a) r[a] = static_cast<int>(std::ceil(opt.exclusion_mm / cg.spacing[a]));
  std::vector<std::uint8_t> excluded = near_mandible;
  for (int a = 0; a < 3; ++a) {
    std::vector<std::uint8_t> next = excluded;
    const long step = a == 0 ? 1L : a == 1 ? static_cast<long>(cg.size[0]) : static_cast<long>(cg.size[0] * cg.size[1]);
    for (std::size_t k = 0; k < cg.size[2]; ++k)
      for (std::size_t j = 0; j < cg.size[1]; ++j)
        for (std::size_t i = 0; i < cg.size[0]; ++i) {
          const std::size_t v = cg.linear(i, j, k);
          if (!excluded[v]) continue;
          const long c = static_cast<long>(a == 0 ? i : a == 1 ? j : k), len = static_cast<long>(cg.size[static_cast<std::size_t>(a)]);
          for (long d = -r[a]; d <= r[a]; ++d)
            if (c + d >= 0 && c + d < len) next[static_cast<std::size_t>(static_cast<long>(v) + d * step)] = 1;
        }
    excluded.swap(next);
  }
  Cranium out;
  out.mask.geom = cg;
  out.mask.data.assign(n, 0);
  const Vec3 up = normalized(opt.floor.normal);
  for (std::size_t k = 0; k < cg.size[2]; ++k)
    for (std::size_t j = 0; j < cg.size[1]; ++j)
      for (std::size_t i = 0; i < cg.size[0]; ++i) {
        const std::size_t v = cg.linear(i, j, k);
        if (excluded[v] || sum[v] < opt.threshold_hu * cnt[v]) continue;
        const Vec3 p = cg.index_to_lps(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
        if (dot(p - opt.floor.point, up) >= 0) out.mask.data[v] = 1;
      }
  // Largest 26-connected component.
  std::vector<int> label(n, 0);
  std::vector<std::size_t> stack;
  int best = 0, next_label = 0;
  std::size_t best_size = 0;
  for (std::size_t s = 0; s < n; ++s) {
    if (!out.mask.data[s] || label[s]) continue;
    label[s] = ++next_label;
    stack.assign(1, s);
    std::size_t size = 0;
    while (!stack.empty()) {
      const std::size_t v = stack.back();
      stack.pop_back();
      ++size;
      const long i = static_cast<long>(v % cg.size[0]), j = static_cast<long>((v / cg.size[0]) % cg.size[1]),
                 k = static_cast<long>(v / (cg.size[0] * cg.size[1]));
      for (long dk = -1; dk <= 1; ++dk)
        for (long dj = -1; dj <= 1; ++dj)
          for (long di = -1; di <= 1; ++di) {
            const long x = i + di, y = j + dj, z = k + dk;
            if (x < 0 || y < 0 || z < 0 || x >= static_cast<long>(cg.size[0]) || y >= static_cast<long>(cg.size[1]) ||
                z >= static_cast<long>(cg.size[2]))
              continue;
            const std::size_t w = cg.linear(static_cast<std::size_t>(x), static_cast<std::size_t>(y), static_cast<std::size_t>(z));
            if (out.mask.data[w] && !label[w]) label[w] = next_label, stack.push_back(w);
          }
    }
    if (size > best_size) best_size = size, best = next_label;
  }
  for (std::size_t v = 0; v < n; ++v) out.mask.data[v] = label[v] == best && best > 0;
  out.volume_cm3 = static_cast<double>(best_size) * cg.voxel_volume_mm3() / 1000;
  return out;
}

}  // namespace ms::segmentation
