#include "segmentation/atlas_zone.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <functional>
#include <limits>
#include <queue>
#include <utility>

namespace ms::segmentation {

std::vector<std::uint8_t> atlas_zone_mask(const std::vector<std::uint8_t>& bone, const std::vector<float>& p,
                                          const std::array<std::size_t, 3>& dims) {
  const std::size_t n = bone.size();
  std::vector<std::uint8_t> out(n, 0);
  // 1. The zone.
  for (std::size_t i = 0; i < n; ++i) out[i] = bone[i] && p[i] >= kAtlasZoneP;
  // 2. Components of the bone outside the zone (26-connected, breadth first):
  //    one touching the zone and staying within the atlas's support joins it.
  const long nx = static_cast<long>(dims[0]), ny = static_cast<long>(dims[1]), nz = static_cast<long>(dims[2]);
  std::vector<std::uint8_t> seen(n, 0);
  std::vector<std::size_t> component;
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (!bone[seed] || out[seed] || seen[seed]) continue;
    component.clear();
    component.push_back(seed);
    seen[seed] = 1;
    bool touches = false, beyond_support = false;
    for (std::size_t head = 0; head < component.size(); ++head) {
      const std::size_t i = component[head];
      beyond_support = beyond_support || p[i] < kAtlasSupportP;
      const long x = static_cast<long>(i % dims[0]), y = static_cast<long>((i / dims[0]) % dims[1]),
                 z = static_cast<long>(i / (dims[0] * dims[1]));
      for (long dz = -1; dz <= 1; ++dz)
        for (long dy = -1; dy <= 1; ++dy)
          for (long dx = -1; dx <= 1; ++dx) {
            const long a = x + dx, b = y + dy, c = z + dz;
            if (a < 0 || b < 0 || c < 0 || a >= nx || b >= ny || c >= nz) continue;
            const std::size_t q = static_cast<std::size_t>((c * ny + b) * nx + a);
            if (!bone[q]) continue;
            if (out[q] && p[q] >= kAtlasZoneP) touches = true;
            else if (!out[q] && !seen[q]) seen[q] = 1, component.push_back(q);
          }
    }
    if (touches && !beyond_support)
      for (std::size_t i : component) out[i] = 1;
  }
  return out;
}

std::vector<std::uint8_t> add_zone_rim(const std::vector<std::uint8_t>& mask, const std::vector<std::uint8_t>& bone,
                                       const std::vector<std::uint8_t>& not_soft, const std::vector<float>& p,
                                       const std::array<std::size_t, 3>& dims, const std::array<double, 3>& spacing,
                                       const std::array<std::array<std::size_t, 2>, 3>& faces) {
  const std::size_t n = mask.size();
  const long nx = static_cast<long>(dims[0]), ny = static_cast<long>(dims[1]), nz = static_cast<long>(dims[2]);
  const double reach = kZoneRimMm + std::max({spacing[0], spacing[1], spacing[2]});
  const float inf = std::numeric_limits<float>::infinity();
  auto for_neighbours = [&](std::size_t i, const std::function<void(std::size_t, double)>& visit) {
    const long x = static_cast<long>(i % dims[0]), y = static_cast<long>((i / dims[0]) % dims[1]),
               z = static_cast<long>(i / (dims[0] * dims[1]));
    for (long dz = -1; dz <= 1; ++dz)
      for (long dy = -1; dy <= 1; ++dy)
        for (long dx = -1; dx <= 1; ++dx) {
          const long a = x + dx, b = y + dy, c = z + dz;
          if ((dx | dy | dz) == 0 || a < 0 || b < 0 || c < 0 || a >= nx || b >= ny || c >= nz) continue;
          visit(static_cast<std::size_t>((c * ny + b) * nx + a),
                std::sqrt(double(dx * dx) * spacing[0] * spacing[0] + double(dy * dy) * spacing[1] * spacing[1] +
                          double(dz * dz) * spacing[2] * spacing[2]));
        }
  };
  // 1. Geodesic distance from the mask through what is not soft tissue
  //    outside it (Dijkstra, 26-neighbour steps), expanded no farther than
  //    `reach`.
  std::vector<float> d(n, inf);
  using Item = std::pair<float, std::size_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> front;
  for (std::size_t i = 0; i < n; ++i)
    if (mask[i]) d[i] = 0, front.push({0.0f, i});
  std::vector<std::size_t> near;  // not soft tissue, within reach, in increasing distance
  while (!front.empty()) {
    const auto [di, i] = front.top();
    front.pop();
    if (di > d[i]) continue;
    if (!mask[i]) near.push_back(i);
    if (di > reach) continue;
    for_neighbours(i, [&](std::size_t q, double step) {
      const float dq = di + static_cast<float>(step);
      if (not_soft[q] && !mask[q] && dq < d[q]) d[q] = dq, front.push({dq, q});
    });
  }
  // 2. Bone that goes on: beyond reach, beyond the support or on a face of
  //    the scanned part (cut by the scan's edge or the atlas's box: it may
  //    go on outside), and, from the farthest in, every voxel with such a voxel
  //    farther out beside it.
  auto on_face = [&](std::size_t i) {
    const long x = static_cast<long>(i % dims[0]), y = static_cast<long>((i / dims[0]) % dims[1]),
               z = static_cast<long>(i / (dims[0] * dims[1]));
    const long at[3] = {x, y, z};
    for (int a = 0; a < 3; ++a)
      if (at[a] <= static_cast<long>(faces[a][0]) || at[a] >= static_cast<long>(faces[a][1])) return true;
    return false;
  };
  std::vector<std::uint8_t> goes_on(n, 0);
  for (auto it = near.rbegin(); it != near.rend(); ++it) {
    const std::size_t i = *it;
    bool on = d[i] > reach || p[i] < kAtlasSupportP || on_face(i);
    if (!on)
      for_neighbours(i, [&](std::size_t q, double) { on = on || (not_soft[q] && !mask[q] && d[q] > d[i] && (goes_on[q] || d[q] > reach)); });
    goes_on[i] = on;
  }
  // 3. The rim: the bone within reach that ends there.
  std::vector<std::uint8_t> out = mask;
  for (std::size_t i : near)
    if (bone[i] && !goes_on[i]) out[i] = 1;
  return out;
}

}  // namespace ms::segmentation
