#include "segmentation/occlusion.h"

// Eigen-facing translation unit (the plane fit): no ITK headers here
// (ENGINEERING.md).
#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

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


// One column of the grid along the column axis, walked upwards.
struct Column {
  const Geometry& g;
  std::size_t ax, ax_a, ax_b, nt;
  int up;
  std::array<std::size_t, 3> ijk{};
  Column(const Geometry& geom, int axis, int up_sign)
      : g(geom), ax(static_cast<std::size_t>(axis)), ax_a(axis == 0 ? 1 : 0), ax_b(axis == 2 ? 1 : 2),
        nt(geom.size[static_cast<std::size_t>(axis)]), up(up_sign) {}
  void at_column(std::size_t a, std::size_t b) { ijk[ax_a] = a, ijk[ax_b] = b; }
  // u counts voxels from the column's inferior end; sets ijk.
  std::size_t voxel(std::size_t u) {
    ijk[ax] = up > 0 ? u : nt - 1 - u;
    return g.linear(ijk[0], ijk[1], ijk[2]);
  }
  Vec3 lps() const { return g.index_to_lps(static_cast<double>(ijk[0]), static_cast<double>(ijk[1]), static_cast<double>(ijk[2])); }
  // Height (mm) of index u along the superior direction, from the column's inferior end.
  double height_mm(double u) const { return u * g.spacing[ax]; }
};

// A run of dense voxels [u0, u1) of a column: welded when, above its
// last zone voxel, it rises at least kWeldRiseMm with enamel on the way.
// Returns the middle (u units) between its lowest and highest enamel voxels
// when welded, else -1.
double welded_run_contact(Column& c, std::size_t u0, std::size_t u1, const Volume& ct,
                          const std::function<double(const Vec3&)>& p, float enamel) {
  long last_zone = -1;
  for (std::size_t u = u0; u < u1; ++u) {
    c.voxel(u);
    if (p(c.lps()) >= kAtlasZoneP) last_zone = static_cast<long>(u);
  }
  if (last_zone < 0 || c.height_mm(static_cast<double>(u1 - 1 - static_cast<std::size_t>(last_zone))) < kWeldRiseMm) return -1;
  long lowest = -1, highest = -1;
  for (std::size_t u = u0; u < u1; ++u)
    if (ct.hu[c.voxel(u)] >= enamel) {
      if (lowest < 0) lowest = static_cast<long>(u);
      highest = static_cast<long>(u);
    }
  return highest > last_zone ? 0.5 * static_cast<double>(lowest + highest) : -1;
}

}  // namespace

WeldedOcclusion welded_occlusion(const Volume& ct, const std::function<double(const Vec3&)>& p, const Vec3& superior,
                                 const Plane& midline, double scale, double dense_hu, double offset_hu) {
  WeldedOcclusion out;
  const Geometry& g = ct.geom;
  const auto [axis, up] = column_axis(g, superior);
  if (axis < 0) return out;
  out.axis = axis, out.up = up;
  Column c(g, axis, up);
  const std::size_t na = g.size[c.ax_a], nb = g.size[c.ax_b];
  const auto dense = static_cast<float>(dense_hu + offset_hu), enamel = static_cast<float>(kEnamelHu + offset_hu);
  for (std::size_t b = 0; b < nb; ++b)
    for (std::size_t a = 0; a < na; ++a) {
      c.at_column(a, b);
      for (std::size_t u = 0; u < c.nt;) {  // the runs of dense voxels
        const std::size_t i = c.voxel(u);
        if (ct.hu[i] < dense) {
          ++u;
          continue;
        }
        const double side = std::abs(dot(c.lps() - midline.point, midline.normal));
        if (side < kPosteriorTeethMm[0] * scale || side > kPosteriorTeethMm[1] * scale) break;  // not the cheek teeth
        std::size_t u1 = u + 1;
        for (; u1 < c.nt; ++u1) {
          const std::size_t j = c.voxel(u1);
          if (ct.hu[j] < dense) break;
        }
        const double mid = welded_run_contact(c, u, u1, ct, p, enamel);
        if (mid >= 0) {
          out.contacts.push_back({static_cast<double>(a) * g.spacing[c.ax_a], static_cast<double>(b) * g.spacing[c.ax_b],
                                  c.height_mm(up > 0 ? mid : static_cast<double>(c.nt - 1) - mid)});
          break;  // one contact per column: its lowest welded run
        }
        u = u1;
      }
    }
  out.columns = out.contacts.size();
  out.area_mm2 = static_cast<double>(out.columns) * g.spacing[c.ax_a] * g.spacing[c.ax_b];
  return out;
}

namespace {

// Huber-weighted least squares of s = c0 + c1 a + c2 b, iteratively
// reweighted; returns the robust scale, or -1 when the contacts are collinear.
double huber_plane(const std::vector<OcclusalContact>& xs, double min_scale, std::array<double, 3>& c) {
  const auto n = static_cast<Eigen::Index>(xs.size());
  Eigen::MatrixXd x(n, 3);
  Eigen::VectorXd s(n), w = Eigen::VectorXd::Ones(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const OcclusalContact& q = xs[static_cast<std::size_t>(k)];
    x.row(k) << 1.0, q.a_mm, q.b_mm;
    s(k) = q.s_mm;
  }
  double scale = min_scale;
  for (int iter = 0; iter < 12; ++iter) {
    const Eigen::Matrix3d normal = x.transpose() * w.asDiagonal() * x;
    const Eigen::FullPivLU<Eigen::Matrix3d> lu(normal);
    if (lu.rank() < 3) return -1;
    const Eigen::Vector3d fit = lu.solve(x.transpose() * w.asDiagonal() * s);
    const Eigen::VectorXd r = (s - x * fit).cwiseAbs();
    std::vector<double> sorted(r.data(), r.data() + n);
    std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
    scale = std::max(min_scale, 1.4826 * sorted[static_cast<std::size_t>(n / 2)]);
    w = r.unaryExpr([scale](double v) { return v <= 2 * scale ? 1.0 : 2 * scale / v; });
    c = {fit(0), fit(1), fit(2)};
  }
  return scale;
}

}  // namespace

OcclusalPlane fit_occlusal_plane(const WeldedOcclusion& weld) {
  OcclusalPlane out;
  if (!weld.welded() || weld.contacts.size() < 3) return out;
  std::array<double, 3> c{};
  out.spread_mm = huber_plane(weld.contacts, 1.0, c);
  if (out.spread_mm < 0) return out;
  out.axis = weld.axis, out.up = weld.up;
  out.c0 = c[0], out.c1 = c[1], out.c2 = c[2];
  out.tilt_deg = std::atan(std::hypot(c[1], c[2])) * 180.0 / 3.14159265358979323846;
  out.found = out.tilt_deg <= kOcclusalMaxTiltDeg;
  return out;
}

std::size_t cut_at_occlusal_plane(Volume& ct, const OcclusalPlane& plane, const WeldedOcclusion& weld, const Plane& midline,
                                  const Vec3& anterior, double offset_hu) {
  if (!plane.found) return 0;
  const Geometry& g = ct.geom;
  Column c(g, plane.axis, plane.up);
  const double h = g.spacing[c.ax], sa = g.spacing[c.ax_a], sb = g.spacing[c.ax_b];
  auto index_at = [&](std::size_t a, std::size_t b) {  // index along the axis of the voxel just above the plane
    const double s = (plane.c0 + plane.c1 * static_cast<double>(a) * sa + plane.c2 * static_cast<double>(b) * sb) / h;
    return plane.up > 0 ? std::ceil(s - 1e-9) : std::floor(s + 1e-9);
  };
  auto lps_at = [&](std::size_t a, std::size_t b, double t) {
    std::array<double, 3> x{};
    x[c.ax_a] = static_cast<double>(a), x[c.ax_b] = static_cast<double>(b), x[c.ax] = t;
    return g.index_to_lps(x[0], x[1], x[2]);
  };
  // The rearmost welded contact along the anterior axis, and the farthest
  // from the midline.
  double rear = std::numeric_limits<double>::infinity(), side = 0;
  for (const OcclusalContact& k : weld.contacts) {
    const auto a = static_cast<std::size_t>(std::lround(k.a_mm / sa)), b = static_cast<std::size_t>(std::lround(k.b_mm / sb));
    const Vec3 q = lps_at(a, b, k.s_mm / h) - midline.point;
    rear = std::min(rear, dot(q, anterior));
    side = std::max(side, std::abs(dot(q, midline.normal)));
  }
  side += kOcclusalCutMarginMm;
  rear -= kOcclusalCutMarginMm;
  const auto air = static_cast<float>(-1000.0 + offset_hu);
  std::size_t changed = 0;
  for (std::size_t b = 0; b < g.size[c.ax_b]; ++b)
    for (std::size_t a = 0; a < g.size[c.ax_a]; ++a) {
      const double t = index_at(a, b);
      if (t < 0 || t >= static_cast<double>(c.nt)) continue;
      const Vec3 q = lps_at(a, b, t);
      if (std::abs(dot(q - midline.point, midline.normal)) > side) continue;
      if (dot(q - midline.point, anterior) < rear) continue;
      c.at_column(a, b);
      const std::size_t i = c.voxel(plane.up > 0 ? static_cast<std::size_t>(t) : c.nt - 1 - static_cast<std::size_t>(t));
      if (ct.hu[i] > air) ++changed;
      ct.hu[i] = air;
    }
  return changed;
}

}  // namespace ms::segmentation
