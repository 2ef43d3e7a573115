#include "segmentation/occlusion.h"

#include <array>
#include <cmath>
#include <utility>

#include "segmentation/atlas_zone.h"

namespace ms::segmentation {
namespace {

// The grid axis nearest the superior axis and +1 when the index grows
// superiorly along it (-1 otherwise); axis -1 when none is within 45 degrees.
std::pair<int, int> column_axis(const Geometry& g, const Vec3& superior) {
  int best = -1;
  double best_dot = 0;
  for (int k = 0; k < 3; ++k) {
    const double d = g.direction[0 * 3 + k] * superior[0] + g.direction[1 * 3 + k] * superior[1] + g.direction[2 * 3 + k] * superior[2];
    if (std::abs(d) > std::abs(best_dot)) best = k, best_dot = d;
  }
  if (std::abs(best_dot) < std::sqrt(0.5)) return {-1, 1};
  return {best, best_dot > 0 ? 1 : -1};
}

}  // namespace

WeldedOcclusion welded_occlusion(const Volume& ct, const Mask& mask, const std::function<double(const Vec3&)>& p,
                                 const Vec3& superior, const Plane& midline, double scale, double dense_hu, double offset_hu) {
  WeldedOcclusion out;
  const Geometry& g = ct.geom;
  const auto [axis, up] = column_axis(g, superior);
  if (axis < 0 || !g.same_grid(mask.geom)) return out;
  const std::size_t ax = static_cast<std::size_t>(axis), ax_a = axis == 0 ? 1 : 0, ax_b = axis == 2 ? 1 : 2;
  const std::size_t na = g.size[ax_a], nb = g.size[ax_b], nt = g.size[ax];
  const auto dense = static_cast<float>(dense_hu + offset_hu), enamel = static_cast<float>(kEnamelHu + offset_hu);
  for (std::size_t b = 0; b < nb; ++b)
    for (std::size_t a = 0; a < na; ++a) {
      // Walk the column upwards: u counts voxels from its inferior end.
      std::array<std::size_t, 3> ijk{};
      ijk[ax_a] = a, ijk[ax_b] = b;
      auto at = [&](std::size_t u) {
        ijk[ax] = up > 0 ? u : nt - 1 - u;
        return g.linear(ijk[0], ijk[1], ijk[2]);
      };
      // In one run of dense mask voxels, going up: the zone, then at least
      // kWeldRiseMm outside it, through enamel.
      bool zone = false, crown = false, welded = false;
      double rise = 0;  // mm above the zone's last voxel in this run
      for (std::size_t u = 0; u < nt && !welded; ++u) {
        const std::size_t i = at(u);
        if (!mask.data[i] || ct.hu[i] < dense) {  // the run ends
          zone = crown = false;
          continue;
        }
        const Vec3 q = g.index_to_lps(static_cast<double>(ijk[0]), static_cast<double>(ijk[1]), static_cast<double>(ijk[2]));
        const double side = std::abs(dot(q - midline.point, midline.normal));
        if (side < kPosteriorTeethMm[0] * scale || side > kPosteriorTeethMm[1] * scale) break;  // not the cheek teeth
        if (p(q) >= kAtlasZoneP) {
          zone = true, crown = false, rise = 0;
          continue;
        }
        if (!zone) continue;
        rise += g.spacing[ax];
        crown = crown || ct.hu[i] >= enamel;
        welded = crown && rise >= kWeldRiseMm;
      }
      out.columns += welded;
    }
  out.area_mm2 = static_cast<double>(out.columns) * g.spacing[ax_a] * g.spacing[ax_b];
  return out;
}

}  // namespace ms::segmentation
