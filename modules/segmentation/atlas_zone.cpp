#include "segmentation/atlas_zone.h"

#include <cstddef>

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

}  // namespace ms::segmentation
