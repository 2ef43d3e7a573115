#include "segmentation/atlas_zone.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <queue>
#include <utility>

namespace ms::segmentation {
namespace {

// The 26 neighbours of a voxel inside a grid, with the length of each step (mm).
class Neighbourhood {
 public:
  Neighbourhood(const std::array<std::size_t, 3>& dims, const std::array<double, 3>& spacing)
      : nx_(static_cast<long>(dims[0])), ny_(static_cast<long>(dims[1])), nz_(static_cast<long>(dims[2])) {
    for (int k = 0; k < 27; ++k) {
      const double d[3] = {(k % 3 - 1) * spacing[0], (k / 3 % 3 - 1) * spacing[1], (k / 9 - 1) * spacing[2]};
      step_[k] = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    }
  }
  // visit(q, step_mm) for each neighbour q of voxel i.
  template <class Visit>
  void each(std::size_t i, Visit&& visit) const {
    const long x = static_cast<long>(i) % nx_, y = static_cast<long>(i) / nx_ % ny_, z = static_cast<long>(i) / (nx_ * ny_);
    for (int k = 0; k < 27; ++k) {
      const long a = x + k % 3 - 1, b = y + k / 3 % 3 - 1, c = z + k / 9 - 1;
      if (k == 13 || a < 0 || b < 0 || c < 0 || a >= nx_ || b >= ny_ || c >= nz_) continue;
      visit(static_cast<std::size_t>((c * ny_ + b) * nx_ + a), step_[k]);
    }
  }

 private:
  long nx_, ny_, nz_;
  double step_[27];
};

}  // namespace

std::vector<std::uint8_t> atlas_zone_mask(const std::vector<std::uint8_t>& bone, const std::vector<float>& p,
                                          const std::array<std::size_t, 3>& dims, const std::function<bool(std::size_t)>& in_room) {
  const std::size_t n = bone.size();
  std::vector<std::uint8_t> out(n, 0);
  // 1. The zone.
  for (std::size_t i = 0; i < n; ++i) out[i] = bone[i] && p[i] >= kAtlasZoneP;
  // 2. Components of the bone outside the zone (26-connected, breadth first):
  //    one touching the zone and staying within the atlas's support, or
  //    wholly within the room of a taller process, joins it.
  const Neighbourhood around(dims, {1.0, 1.0, 1.0});
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
      around.each(i, [&](std::size_t q, double) {
        if (!bone[q]) return;
        if (out[q] && p[q] >= kAtlasZoneP) touches = true;
        else if (!out[q] && !seen[q]) seen[q] = 1, component.push_back(q);
      });
    }
    if (touches && (!beyond_support || (in_room && std::all_of(component.begin(), component.end(), in_room))))
      for (std::size_t i : component) out[i] = 1;
  }
  return out;
}

std::vector<std::uint8_t> add_zone_rim(const std::vector<std::uint8_t>& mask, const std::vector<std::uint8_t>& bone,
                                       const std::vector<std::uint8_t>& not_soft, const std::vector<float>& p,
                                       const std::array<std::size_t, 3>& dims, const std::array<double, 3>& spacing,
                                       const std::array<std::array<std::size_t, 2>, 3>& faces) {
  const std::size_t n = mask.size();
  const Neighbourhood around(dims, spacing);
  const double reach = kZoneRimMm + std::max({spacing[0], spacing[1], spacing[2]});
  const float inf = std::numeric_limits<float>::infinity();
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
    around.each(i, [&](std::size_t q, double step) {
      const float dq = di + static_cast<float>(step);
      if (not_soft[q] && !mask[q] && dq < d[q]) d[q] = dq, front.push({dq, q});
    });
  }
  // 2. Bone that goes on: beyond reach, beyond the support or on a face of
  //    the scanned part (cut by the scan's edge or the atlas's box: it may
  //    go on outside), and, from the farthest in, every voxel with such a
  //    voxel farther out beside it (a finite larger distance: reached, so
  //    outside the mask and not soft tissue).
  auto on_face = [&](std::size_t i) {
    const std::size_t at[3] = {i % dims[0], i / dims[0] % dims[1], i / (dims[0] * dims[1])};
    for (int a = 0; a < 3; ++a)
      if (at[a] <= faces[a][0] || at[a] >= faces[a][1]) return true;
    return false;
  };
  std::vector<std::uint8_t> goes_on(n, 0);
  for (auto it = near.rbegin(); it != near.rend(); ++it) {
    const std::size_t i = *it;
    bool on = d[i] > reach || p[i] < kAtlasSupportP || on_face(i);
    if (!on)
      around.each(i, [&](std::size_t q, double) { on = on || (goes_on[q] && d[q] > d[i]); });
    goes_on[i] = on;
  }
  // 3. The rim: the bone within reach that ends there.
  std::vector<std::uint8_t> out = mask;
  for (std::size_t i : near)
    if (bone[i] && !goes_on[i]) out[i] = 1;
  return out;
}

std::vector<std::uint8_t> extend_to_joint_space(const std::vector<std::uint8_t>& mask, const std::vector<std::uint8_t>& bone,
                                                const std::array<std::size_t, 3>& dims, int up_axis, int up_step, double up_mm,
                                                const std::function<bool(std::size_t)>& in_room) {
  std::vector<std::uint8_t> out = mask;
  const std::size_t stride[3] = {1, dims[0], dims[0] * dims[1]};
  const long n_up = static_cast<long>(dims[up_axis]);
  const long max_bone = static_cast<long>(std::floor(kZoneRimMm / up_mm + 1e-9));
  const long max_gap = static_cast<long>(std::floor(kJointGapMaxMm / up_mm + 1e-9));
  std::vector<std::size_t> top;
  for (std::size_t i = 0; i < mask.size(); ++i) {
    if (!mask[i]) continue;
    const long at = static_cast<long>(i / stride[up_axis] % dims[up_axis]);
    auto voxel = [&](long steps) -> std::ptrdiff_t {  // steps up from i, or -1 outside the grid
      const long c = at + up_step * steps;
      if (c < 0 || c >= n_up) return -1;
      return static_cast<std::ptrdiff_t>(i) + up_step * steps * static_cast<std::ptrdiff_t>(stride[up_axis]);
    };
    // 1. The bone above the mask's top voxel in this column, up to the gap.
    top.clear();
    long s = 1;
    for (std::ptrdiff_t q; (q = voxel(s)) >= 0 && bone[q] && !mask[q]; ++s) top.push_back(static_cast<std::size_t>(q));
    if (top.empty() || static_cast<long>(top.size()) > max_bone || voxel(s) < 0 || mask[voxel(s)]) continue;
    // 2. The gap: non-bone, then bone again (the fossa's roof) within kJointGapMaxMm.
    const long gap_from = s;
    for (std::ptrdiff_t q; (q = voxel(s)) >= 0 && !bone[q] && s - gap_from < max_gap; ++s) {}
    const std::ptrdiff_t roof = voxel(s);
    if (roof < 0 || !bone[roof] || mask[roof]) continue;
    // 3. The condyle's top: that bone, where a process may stand.
    if (std::all_of(top.begin(), top.end(), in_room))
      for (std::size_t q : top) out[q] = 1;
  }
  return out;
}

}  // namespace ms::segmentation
