#include "phantom/anatomy.h"

#include <cmath>
#include <limits>

#include "core/hull2d.h"

namespace ms::phantom {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kFar = 1e9;
constexpr double kRamusTiltDeg = 10.0;

// Catmull-Rom resampling of a 2D control polygon into n points per span.
std::vector<sdf::P2> catmull_rom(const std::vector<sdf::P2>& c, int n) {
  std::vector<sdf::P2> out;
  const int m = static_cast<int>(c.size());
  for (int i = 0; i + 1 < m; ++i) {
    const sdf::P2 p0 = c[std::max(i - 1, 0)], p1 = c[i], p2 = c[i + 1], p3 = c[std::min(i + 2, m - 1)];
    for (int k = 0; k < n; ++k) {
      const double t = static_cast<double>(k) / n, t2 = t * t, t3 = t2 * t;
      auto f = [&](double a, double b, double cc, double d) {
        return 0.5 * (2 * b + (-a + cc) * t + (2 * a - 5 * b + 4 * cc - d) * t2 + (-a + 3 * b - 3 * cc + d) * t3);
      };
      out.push_back({f(p0.x, p1.x, p2.x, p3.x), f(p0.y, p1.y, p2.y, p3.y)});
    }
  }
  out.push_back(c.back());
  return out;
}

double lerp(double a, double b, double t) { return a + (b - a) * t; }

// Upward column search: highest z in [z0, z1] where f < 0 at (x, y).
template <class F>
double top_crossing(const F& f, double x, double y, double z0, double z1) {
  double z = z1;
  if (f(Vec3{x, y, z}) < 0) return z1;
  const double step = 0.5;
  while (z > z0 && f(Vec3{x, y, z - step}) >= 0) z -= step;
  if (z <= z0) return -kFar;
  double hi = z, lo = z - step;  // f(lo) < 0 <= f(hi)
  for (int i = 0; i < 30; ++i) {
    const double mid = 0.5 * (lo + hi);
    (f(Vec3{x, y, mid}) < 0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Bisection of the surface crossing between an outside point a and inside point b.
template <class F>
Vec3 crossing(const F& f, Vec3 a, Vec3 b) {
  // March from a towards b until inside, then bisect.
  const double len = distance(a, b);
  const int n = static_cast<int>(std::ceil(len / 0.25));
  Vec3 prev = a;
  for (int i = 1; i <= n; ++i) {
    const Vec3 q = a + (static_cast<double>(i) / n) * (b - a);
    if (f(q) < 0) {
      Vec3 lo = prev, hi = q;
      for (int k = 0; k < 40; ++k) {
        const Vec3 mid = 0.5 * (lo + hi);
        (f(mid) < 0 ? hi : lo) = mid;
      }
      return 0.5 * (lo + hi);
    }
    prev = q;
  }
  return b;
}

}  // namespace

// The ramus mid-surface splays outward towards the condyle and turns so that
// its anterior border lies medial to its posterior border (the rami diverge
// posteriorly in axial view).
double SideModel::mid_x(double f, double u) const {
  return x_at_corner + (x_at_top - x_at_corner) * (u / ramus_top) - f * std::tan(10.0 * 3.14159265358979323846 / 180.0);
}

Vec3 SideModel::local(const Vec3& p) const {
  const double u = p[2] - corner[2];
  const double f = -(p[1] - corner[1]);
  return {f, u, s * p[0] - mid_x(f, u)};
}

Vec3 SideModel::to_h(double f, double u, double n) const {
  return {s * (mid_x(f, u) + n), corner[1] - f, corner[2] + u};
}

Anatomy::Anatomy(const PhantomParams& p) : p_(p) {
  // ---- body centreline (left half; right half mirrored), H frame (x, y) ----
  // Intermolar width ~50 mm, bigonial width ~91 mm: the molars sit well
  // medial to the anterior ramus border (retromolar region), as in adults.
  const std::vector<sdf::P2> ctrl = {{0, -70}, {8, -68}, {16.5, -63.5}, {22, -55}, {25, -45},
                                     {28, -35}, {33, -26}, {40, -17.5}, {45.5, -11}};
  const auto base = catmull_rom(ctrl, 8);
  std::vector<double> arc(base.size(), 0.0);
  for (std::size_t i = 1; i < base.size(); ++i)
    arc[i] = arc[i - 1] + std::hypot(base[i].x - base[i - 1].x, base[i].y - base[i - 1].y);
  base_arch_ = base;
  base_t_.clear();
  for (double a : arc) base_t_.push_back(a / arc.back());
  for (int si = 0; si < 2; ++si) {
    const double s = si == 0 ? 1.0 : -1.0;
    const SideAsymmetry& a = p_.side[si];
    arch_[si].clear();
    arch_t_[si].clear();
    for (std::size_t i = 0; i < base.size(); ++i) {
      const double t = arc[i] / arc.back();
      // Body lengthening moves the angle posteriorly, tapering to 0 at the
      // symphysis; chin deviation shifts the symphysis, tapering to 0 at the angle.
      arch_[si].push_back({s * base[i].x + p_.chin_deviation_mm * (1.0 - t), base[i].y + a.body_length_mm * t});
      arch_t_[si].push_back(t);
    }
  }

  // ---- rami ----
  for (int si = 0; si < 2; ++si) {
    SideModel& m = side_[si];
    const SideAsymmetry& a = p_.side[si];
    m.s = si == 0 ? 1.0 : -1.0;
    const sdf::P2 end = arch_[si].back();
    m.corner = {end.x, end.y, -56.0};
    m.x_at_corner = std::abs(end.x) - 0.5;
    m.x_at_top = m.x_at_corner + 5.0;
    // Ramus outline (f anterior, u superior) relative to the angle corner:
    // angle, anterior border, coronoid, sigmoid notch, condylar neck, posterior border.
    std::vector<sdf::P2> poly = {{0, 0},    {30, -2},  {28, 18},  {26, 32},  {28, 42},  {27, 47},
                                 {24, 51},  {21, 48},  {16, 44},  {12, 41.5}, {7, 40.5}, {2, 43},
                                 {-2, 48},  {-4, 52},  {-13, 52}, {-15, 46}, {-9, 22}};
    sdf::P2 head{-8.5, 55.0};
    sdf::P2 cor{24, 51};  // coronoid tip ~3 mm below the condylion after the tilt
    // Ramus height: stretch the ramus plate above the angle vertically; the head moves up with its top.
    const double h0 = 60.0;  // condylion height above the corner, unmodified
    const double scale = (h0 + a.ramus_height_mm) / h0;
    // Gonial angle: rotate about the corner, positive opens the angle (top
    // tilts back). The unmodified ramus is tilted back 10° so the Co–Go–Me
    // angle is about 120°, an adult norm.
    const double ang = (kRamusTiltDeg + a.gonial_angle_deg) * kPi / 180.0;
    auto xf = [&](sdf::P2 q) {
      q.y *= scale;
      const double c = std::cos(ang), sn = std::sin(ang);
      return sdf::P2{c * q.x - sn * q.y, sn * q.x + c * q.y};
    };
    for (auto& q : poly) q = xf(q);
    m.polygon = poly;
    // The condylar head is not stretched: it rides on top of the ramus, so
    // the condylion rises by exactly the knob along the ramus axis.
    m.head_fu = xf({head.x, (head.y + a.ramus_height_mm) / scale});
    m.coronoid_fu = xf(cor);
    m.ramus_top = 60.0 * scale;
    m.head_center = m.to_h(m.head_fu.x, m.head_fu.y, -1.5);
    const double dc = a.condyle_size_mm / 2.0;
    m.head_axes = {9.5 + dc, 4.5 + dc, 5.0 + dc};
  }

  // ---- chin (mental protuberance) ----
  chin_center_ = {p_.chin_deviation_mm, -75.0, -68.0};
  chin_axes_ = {12.0, 5.0, 8.0};

  place_teeth(base);
  set_mandible_box();
}

// Teeth: central incisor .. second molar along each lower arch, and the upper
// arch (the unmodified arch scaled up for overjet) above them.
void Anatomy::place_teeth(const std::vector<sdf::P2>& base) {
  struct Kind {
    double md, bl, crown, root;
  };
  const Kind lower_k[7] = {{5.4, 6.0, 9.0, 12.5}, {5.9, 6.2, 9.0, 14}, {6.9, 7.6, 10, 16}, {7.0, 7.8, 8.5, 14},
                           {7.2, 8.2, 8, 14.5},    {11.0, 10.4, 7.5, 14}, {10.5, 10.0, 7, 13}};
  const Kind upper_k[7] = {{8.6, 7.0, 10.5, 13}, {6.6, 6.2, 9, 13}, {7.6, 8.0, 10, 17}, {7.0, 9.0, 8.5, 14},
                           {6.7, 9.0, 7.8, 14},  {10.2, 11.0, 7.5, 13}, {9.2, 11.0, 7.2, 13}};
  auto place = [&](const std::vector<sdf::P2>& line, const std::vector<double>& tt, const Kind* kinds,
                   double grow, double scale_xy, std::vector<Tooth>& out, int si) {
    // cumulative arc length along the (possibly scaled) line
    std::vector<sdf::P2> pts = line;
    for (auto& q : pts) q = {q.x * scale_xy, (q.y + 11.0) * scale_xy - 11.0};
    std::vector<double> L(pts.size(), 0.0);
    for (std::size_t i = 1; i < pts.size(); ++i)
      L[i] = L[i - 1] + std::hypot(pts[i].x - pts[i - 1].x, pts[i].y - pts[i - 1].y);
    double acc = 0.15;  // half the interproximal gap at the midline
    for (int k = 0; k < 7; ++k) {
      const double c = acc + kinds[k].md / 2.0;
      acc += kinds[k].md + 0.3;
      std::size_t i = 1;
      while (i + 1 < pts.size() && L[i] < c) ++i;
      const double w = (c - L[i - 1]) / (L[i] - L[i - 1]);
      const double x = lerp(pts[i - 1].x, pts[i].x, w), y = lerp(pts[i - 1].y, pts[i].y, w);
      const double t = lerp(tt[i - 1], tt[i], w);
      Vec3 tan = normalized(Vec3{pts[i].x - pts[i - 1].x, pts[i].y - pts[i - 1].y, 0});
      Tooth th;
      th.tangent = tan;
      th.normal = {-tan[1], tan[0], 0};
      const double z = z_occlusal(t) + (grow > 0 ? 0.5 : -0.5) * p_.occlusal_gap_mm;
      th.base = {x, y, z};
      th.half_md = p_.crown_scale * kinds[k].md / 2.0;
      th.half_bl = p_.crown_scale * kinds[k].bl / 2.0;
      th.crown_h = p_.crown_scale * kinds[k].crown;
      th.root_len = kinds[k].root;
      th.dir = grow;
      out.push_back(th);
      if (p_.metal && k == 5 && grow < 0) metal_.push_back({x, y, z - 2.2});
      (void)si;
    }
  };
  for (int si = 0; si < 2; ++si) {
    place(arch_[si], arch_t_[si], lower_k, -1.0, 1.0, lower_, si);
    // The upper arch is the unmodified arch scaled up for overjet; the maxilla
    // does not follow mandibular asymmetry.
    std::vector<sdf::P2> up;
    const double s = si == 0 ? 1.0 : -1.0;
    for (std::size_t i = 0; i < base.size(); ++i) up.push_back({s * base[i].x, base[i].y});
    place(up, arch_t_[si], upper_k, +1.0, 1.045, upper_, si);
  }

}

void Anatomy::set_mandible_box() {
  // Box containing the mandible (with room for the asymmetry knobs).
  double grow = 0;
  for (const auto& a : p_.side)
    grow = std::max({grow, std::abs(a.ramus_height_mm), std::abs(a.body_length_mm), std::abs(a.condyle_size_mm),
                     std::abs(a.gonial_angle_deg) * 1.1});
  grow += std::abs(p_.chin_deviation_mm) + 4.0;
  mand_lo_ = {-66 - grow, -86 - grow, -86 - grow};
  mand_hi_ = {66 + grow, 14 + grow, 12 + grow};
}

Anatomy::ArchHit Anatomy::arch_distance(double x, double y) const {
  ArchHit best{kFar, 0};
  double best2 = kFar;
  for (int si = 0; si < 2; ++si) {
    const auto& a = arch_[si];
    const auto& tt = arch_t_[si];
    for (std::size_t i = 1; i < a.size(); ++i) {
      const double ex = a[i].x - a[i - 1].x, ey = a[i].y - a[i - 1].y;
      const double wx = x - a[i - 1].x, wy = y - a[i - 1].y;
      const double h = sdf::clamp01((wx * ex + wy * ey) / (ex * ex + ey * ey));
      const double dx = wx - h * ex, dy = wy - h * ey, d2 = dx * dx + dy * dy;
      if (d2 < best2) {
        best2 = d2;
        best.t = lerp(tt[i - 1], tt[i], h);
      }
    }
  }
  best.d = std::sqrt(best2);
  return best;
}

double Anatomy::z_crest(double t) const {
  // Alveolar crest rising slightly towards the molars; behind them the body
  // keeps its height and merges into the ramus (external oblique line).
  return -44.0 + 6.0 * std::min(t, 0.72);
}

double Anatomy::body(const Vec3& p) const {
  const ArchHit h = arch_distance(p[0], p[1]);
  const double zl = z_lower(h.t), zu = z_crest(h.t);
  const double hfrac = sdf::clamp01((p[2] - zl) / (zu - zl));
  const double base_hw = h.t < 0.5 ? lerp(7.0, 6.0, h.t / 0.5) : lerp(6.0, 5.6, (h.t - 0.5) / 0.5);
  const double hw = base_hw * (1.0 - 0.35 * hfrac);
  const double r = 2.0;
  const double dz = std::max(zl - p[2], p[2] - zu) + r;
  return sdf::extrude(h.d - hw + r, dz) - r;
}

double Anatomy::ramus(const SideModel& m, const Vec3& p) const {
  const Vec3 q = m.local(p);
  const double r_edge = 1.6, r_plane = 2.0;
  const double d2 = sdf::polygon(m.polygon, {q[0], q[1]}) - r_plane;
  const double plate = sdf::extrude(d2 + r_edge, std::abs(q[2]) - 2.0) - r_edge;
  // Condylar head: ellipsoid, long axis medio-lateral, medial pole turned 15° posteriorly.
  const Vec3 d = p - m.head_center;
  const double c = std::cos(15.0 * kPi / 180.0), sn = std::sin(15.0 * kPi / 180.0);
  const Vec3 loc{m.s * d[0] * c - d[1] * sn, m.s * d[0] * sn + d[1] * c, d[2]};
  const double head = sdf::ellipsoid(loc, m.head_axes);
  return sdf::smin(plate, head, 2.5);
}

double Anatomy::mandible_bone(const Vec3& p) const {
  if (p[0] < mand_lo_[0] || p[1] < mand_lo_[1] || p[2] < mand_lo_[2] || p[0] > mand_hi_[0] || p[1] > mand_hi_[1] ||
      p[2] > mand_hi_[2])
    return kFar;
  double d = body(p);
  d = sdf::smin(d, sdf::ellipsoid(p - chin_center_, chin_axes_), 3.0);
  const SideModel& m = p[0] >= 0 ? side_[0] : side_[1];
  d = sdf::smin(d, ramus(m, p), 6.0);
  // The other ramus matters only near the midline (never, in practice), skip it.
  return d;
}

double Anatomy::teeth(const std::vector<Tooth>& set, const Vec3& p, bool crown_only) const {
  double best = kFar;
  for (const Tooth& t : set) {
    const Vec3 d = p - t.base;
    const double a = dot(d, t.tangent), b = dot(d, t.normal);
    if (std::abs(a) > 12 || std::abs(b) > 12) continue;
    // crown: rounded elliptic cylinder from the occlusal end over crown_h
    const double zc = t.dir * d[2];  // distance into the tooth from the occlusal end
    const double rr = std::min(t.half_md, t.half_bl);
    const double ell = (std::sqrt(a * a / (t.half_md * t.half_md) + b * b / (t.half_bl * t.half_bl)) - 1.0) * rr;
    // Crown: a rounded elliptic cylinder ending in a domed occlusal cap
    // (cusps make point contacts in occlusion, never full-area contact).
    const double r = 1.4, cap = 2.5;
    const double body_h = t.crown_h - cap;
    const double cyl = sdf::extrude(ell + r, std::abs(zc - cap - body_h / 2) - body_h / 2 + r) - r;
    const double dome = sdf::ellipsoid(Vec3{a, b, zc - cap}, Vec3{t.half_md, t.half_bl, cap});
    const double crown = sdf::smin(cyl, dome, 0.8);
    double dd = crown;
    if (!crown_only) {
      const Vec3 top = t.base - (t.dir * (t.crown_h - 1.0)) * Vec3{0, 0, -1};
      const Vec3 apex = t.base - (t.dir * (t.crown_h + t.root_len)) * Vec3{0, 0, -1};
      dd = sdf::smin(dd, sdf::capsule(p, top, apex, 0.55 * rr), 1.0);
    }
    best = std::min(best, dd);
  }
  return best;
}

double Anatomy::lower_teeth(const Vec3& p, bool crown_only) const {
  if (p_.edentulous) return kFar;
  if (p[2] > -15 || p[2] < -70 || p[1] < -90 || p[1] > 0) return kFar;
  return teeth(lower_, p, crown_only);
}

double Anatomy::upper_teeth(const Vec3& p, bool crown_only) const {
  if (p_.edentulous) return kFar;
  if (p[2] < -50 || p[2] > 5 || p[1] < -92 || p[1] > 0) return kFar;
  return teeth(upper_, p, crown_only);
}

double Anatomy::mandible(const Vec3& p) const { return std::min(mandible_bone(p), lower_teeth(p, false)); }

double Anatomy::skull_base(const Vec3& p) const {
  // Floor of the middle cranial fossa / temporal bones with the articular
  // eminences; the glenoid fossae are carved by the mandible grown by the joint space.
  if (std::abs(p[0]) > 75 || p[1] < -30 || p[1] > 50 || p[2] < -12 || p[2] > 34) return kFar;
  double d = sdf::round_box(p - Vec3{0, 14, 14}, {68, 34, 14}, 4.0);
  for (double s : {1.0, -1.0}) d = sdf::smin(d, sdf::ellipsoid(p - Vec3{s * 50, -3, 1}, {11, 6, 5}), 2.0);
  if (d > 3.0) return d;
  return std::max(d, p_.joint_space_mm - mandible(p));
}

double Anatomy::maxilla(const Vec3& p) const {
  if (std::abs(p[0]) > 60 || p[1] < -95 || p[1] > -5 || p[2] < -40 || p[2] > 25) return kFar;
  const double zo = z_occlusal(0.0);
  // alveolar process along the (overjet-scaled) arch
  // alveolar process along the symmetric arch scaled for overjet (the maxilla
  // does not follow mandibular asymmetry)
  ArchHit h{kFar, 0};
  {
    const double x = std::abs(p[0]) / 1.045, y = (p[1] + 11.0) / 1.045 - 11.0;
    double b2 = kFar;
    for (std::size_t i = 1; i < base_arch_.size(); ++i) {
      const sdf::P2 a = base_arch_[i - 1], b = base_arch_[i];
      const double ex = b.x - a.x, ey = b.y - a.y, wx = x - a.x, wy = y - a.y;
      const double hh = sdf::clamp01((wx * ex + wy * ey) / (ex * ex + ey * ey));
      const double dx = wx - hh * ex, dy = wy - hh * ey, d2 = dx * dx + dy * dy;
      if (d2 < b2) {
        b2 = d2;
        h.t = lerp(base_t_[i - 1], base_t_[i], hh);
      }
    }
    h.d = std::sqrt(b2) * 1.045;
  }
  double d = kFar;
  if (h.t < 0.68) {  // the tuberosity ends just behind the second molar
    const double zb = z_occlusal(h.t) + 8.5, zt = zo + 26.0;
    d = sdf::extrude(h.d - 6.0 + 2.0, std::max(zb - p[2], p[2] - zt) + 2.0) - 2.0;
  }
  // maxillary body with palate, hollowed by sinuses and the nasal cavity
  double body = sdf::round_box(p - Vec3{0, -47, zo + 34}, {35, 27, 15}, 6.0);
  const double walls = 0.0;  // cavity walls come from the box rounding
  double cav = sdf::round_box(p - Vec3{0, -45, zo + 39}, {10, 26, 11}, 3.0);
  for (double s : {1.0, -1.0}) cav = std::min(cav, sdf::ellipsoid(p - Vec3{s * 21, -47, zo + 36}, {10, 17, 10}));
  body = std::max(body, -(cav - walls));
  d = sdf::smin(d, body, 3.0);
  // zygomatic arches
  for (double s : {1.0, -1.0}) d = std::min(d, sdf::capsule(p, {s * 56, -58, -4}, {s * 65, -16, 3}, 3.0));
  return d;
}

double Anatomy::spine(const Vec3& p, bool cancellous) const {
  if (std::abs(p[0]) > 30 || p[1] < 10 || p[1] > 80 || p[2] > 0 || p[2] < -130) return kFar;
  const double shrink = cancellous ? 1.5 : 0.0;
  double d = kFar;
  // atlas ring and dens
  {
    const Vec3 q = p - Vec3{0, 34, -14};
    const double ring = std::hypot(std::hypot(q[0], q[1]) - 14.0, q[2]) - 3.5;
    d = std::min(d, ring + shrink);
  }
  d = std::min(d, sdf::capsule(p, {0, 30, -26}, {0, 30, -10}, 4.5 - shrink));
  for (int i = 0; i < 6; ++i) {
    const double zc = -34.0 - 16.0 * i;
    const Vec3 q = p - Vec3{0, 31, zc};
    const double cyl = sdf::extrude(std::hypot(q[0] / 1.1, q[1]) - 8.0 + 1.5, std::abs(q[2]) - 6.0 + 1.5) - 1.5;
    d = std::min(d, cyl + shrink);
    if (!cancellous) {
      for (double s : {1.0, -1.0}) d = std::min(d, sdf::capsule(p, {s * 7, 38, zc + 2}, {s * 4, 52, zc + 1}, 2.5));
      d = std::min(d, sdf::capsule(p, {0, 52, zc + 1}, {0, 66, zc - 4}, 3.0));
    }
  }
  return d;
}

double Anatomy::hu(const Vec3& p, double w) const {
  auto cover = [w](double d) { return sdf::clamp01(0.5 - d / w); };
  auto paint = [](double& v, double alpha, double value) { v += alpha * (value - v); };
  double v = -1000.0;
  // soft tissue: head, face and neck
  double soft = sdf::ellipsoid(p - Vec3{0, 5, 35}, {80, 100, 95});
  soft = sdf::smin(soft, sdf::round_box(p - Vec3{0, -28, -40}, {62, 62, 50}, 18.0), 8.0);
  soft = sdf::smin(soft, sdf::extrude(std::hypot(p[0] / 55.0, (p[1] - 15) / 50.0) * 50.0 - 50.0, -(p[2] + 60) - 90), 10.0);
  if (soft > w) return v;
  paint(v, cover(soft), 45.0);
  // brain
  paint(v, cover(sdf::ellipsoid(p - Vec3{0, 5, 35}, {67, 87, 81})), 35.0);
  // air: pharynx, nasal cavity, sinuses, oral vestibule between the lips? (not modelled)
  const double zo = z_occlusal(0.0);
  double air = sdf::capsule(p, {0, 12, -2}, {0, 14, -125}, 7.0);
  air = std::min(air, sdf::round_box(p - Vec3{0, -45, zo + 39}, {10, 26, 11}, 3.0));
  for (double s : {1.0, -1.0}) air = std::min(air, sdf::ellipsoid(p - Vec3{s * 21, -47, zo + 36}, {10, 17, 10}));
  paint(v, cover(air), -1000.0);
  // skull vault (shell above the skull base)
  {
    const Vec3 q = p - Vec3{0, 5, 35};
    const double outer = sdf::ellipsoid(q, {74, 94, 88}), inner = sdf::ellipsoid(q, {68, 88, 82});
    const double shell = std::max({outer, -inner, 10.0 - p[2]});
    paint(v, cover(shell), 1400.0);
  }
  paint(v, cover(skull_base(p)), 1250.0);
  paint(v, cover(maxilla(p)), 1150.0);
  paint(v, cover(spine(p, false)), 1100.0);
  paint(v, cover(spine(p, true)), 300.0);
  {
    double hy = sdf::capsule(p, {-10, -28, -98}, {10, -28, -98}, 3.0);
    for (double s : {1.0, -1.0}) hy = std::min(hy, sdf::capsule(p, {s * 10, -28, -98}, {s * 21, -6, -95}, 2.0));
    paint(v, cover(hy), 950.0);
  }
  paint(v, cover(upper_teeth(p, false)), 1800.0);
  paint(v, cover(upper_teeth(p, true)), 2600.0);
  // mandible: cortical shell (cortex_mm) over a cancellous core
  const double mb = mandible_bone(p);
  if (mb < w + p_.cortex_mm + 0.5) {
    paint(v, cover(mb), p_.cortical_hu);
    paint(v, cover(mb + p_.cortex_mm), p_.cancellous_hu);
  }
  paint(v, cover(lower_teeth(p, false)), 1800.0);
  paint(v, cover(lower_teeth(p, true)), 2600.0);
  for (const Vec3& m : metal_) paint(v, cover(sdf::ellipsoid(p - m, {3.0, 2.6, 1.8})), 8000.0);
  return v;
}

namespace {

// Co, Cr: the most superior surface point of the bone f over the columns
// within (rx, ry) of c. The centroid of the near-highest columns: flat tops
// (the coronoid edge is flat across the plate) must not be decided by scan order.
template <class F>
Vec3 highest_point(const F& f, const Vec3& c, double rx, double ry) {
  std::vector<Vec3> tops;
  double zmax = -kFar;
  for (double dx = -rx; dx <= rx + 1e-9; dx += 0.25)
    for (double dy = -ry; dy <= ry + 1e-9; dy += 0.25) {
      const double z = top_crossing(f, c[0] + dx, c[1] + dy, c[2] - 4.0, c[2] + 20.0);
      tops.push_back({c[0] + dx, c[1] + dy, z});
      zmax = std::max(zmax, z);
    }
  Vec3 acc{0, 0, 0};
  int cnt = 0;
  for (const Vec3& t : tops)
    if (t[2] > zmax - 0.05) {
      acc = acc + t;
      ++cnt;
    }
  const Vec3 xy = (1.0 / cnt) * acc;
  return Vec3{xy[0], xy[1], top_crossing(f, xy[0], xy[1], c[2] - 4.0, c[2] + 20.0)};
}

// A direction in the sagittal projection (y, z), unit.
struct SagittalDir {
  double ny = 0, nz = -1;
};

// A hull edge of the sagittal outline: its length and outward normal.
struct HullEdge {
  double len, ny, nz;
};

// Go, the tangents: the outline's hull edges (counter-clockwise in (y, z))
// within 50 degrees of posterior / inferior, each facing the nearer of the
// two (as the detector, docs/landmarks.md: with the gonial angle opened 8
// degrees the lower posterior border faced 40 degrees below posterior, was in
// both cones, and paired with the upper posterior border put gonion half-way
// up the ramus); of the distinct pairs, the one with the largest total
// length. Returns the pair's outward normals.
struct GonialTangents {
  SagittalDir post, inf;
};
GonialTangents gonial_tangents(const std::vector<Vec3>& outline, const std::vector<std::size_t>& h) {
  std::vector<HullEdge> post, inf;
  const double cone = std::cos(50.0 * kPi / 180.0);
  for (std::size_t i = 0; i < h.size(); ++i) {
    const Vec3 &a = outline[h[i]], &b = outline[h[(i + 1) % h.size()]];
    const double dy = b[1] - a[1], dz = b[2] - a[2], len = std::hypot(dy, dz);
    if (len < 1e-9) continue;
    const HullEdge e{len, dz / len, -dy / len};  // outward normal of a counter-clockwise hull
    if (e.ny > cone && e.ny >= -e.nz) post.push_back(e);  // +y: posterior
    if (-e.nz > cone && -e.nz > e.ny) inf.push_back(e);
  }
  double best_len = -1;
  GonialTangents t;
  for (const HullEdge& pe : post)
    for (const HullEdge& ie : inf)
      if (-pe.nz < -ie.nz && pe.len + ie.len > best_len) {
        best_len = pe.len + ie.len;
        t.post = {pe.ny, pe.nz};
        t.inf = {ie.ny, ie.nz};
      }
  return t;
}

// Go (METHOD.md §2, as docs/landmarks.md measures it: the constructed
// gonion): in the sagittal projection (y, z) of this side, the posterior
// ramus tangent and the inferior border tangent are the outline's support
// lines with the normals of gonial_tangents; they meet at T, and gonion is
// the first point of the bone's projection on their angle's bisector,
// followed from T into the bone (0.05 mm steps; bone at any x within 15 mm
// of the outline's corner), then put on the surface along the bisector at
// the middle of the bone across the plate. The tangents come from the
// design outline, the crossing from the bone itself: offsetting both
// tangents by the same margin (the bone's rounded rim around the outline)
// moves T along the same bisector, so the crossing does not depend on it.
template <class F>
Vec3 gonion(const F& f, const std::vector<Vec3>& outline) {
  std::vector<std::array<double, 2>> yz(outline.size());
  for (std::size_t i = 0; i < outline.size(); ++i) yz[i] = {outline[i][1], outline[i][2]};
  const std::vector<std::size_t> h = convex_hull_2d(yz);  // counter-clockwise in (y, z)
  const GonialTangents g = gonial_tangents(outline, h);
  double cp = -kFar, ci = -kFar;
  for (std::size_t i : h) {
    cp = std::max(cp, g.post.ny * yz[i][0] + g.post.nz * yz[i][1]);
    ci = std::max(ci, g.inf.ny * yz[i][0] + g.inf.nz * yz[i][1]);
  }
  const double det = g.post.ny * g.inf.nz - g.post.nz * g.inf.ny;
  const double ty = (cp * g.inf.nz - g.post.nz * ci) / det, tz = (g.post.ny * ci - cp * g.inf.ny) / det;
  const double bl = std::hypot(g.post.ny + g.inf.ny, g.post.nz + g.inf.nz);
  const double by = (g.post.ny + g.inf.ny) / bl, bz = (g.post.nz + g.inf.nz) / bl;  // outward
  std::size_t corner = h.front();
  for (std::size_t i : h)
    if (yz[i][0] * by + yz[i][1] * bz > yz[corner][0] * by + yz[corner][1] * bz) corner = i;
  const double xc = outline[corner][0];
  for (double s = -10.0; s <= 40.0; s += 0.05) {
    const double y = ty - s * by, z = tz - s * bz;
    double x0 = kFar, x1 = -kFar;
    for (double x = xc - 15.0; x <= xc + 15.0; x += 0.1)
      if (f(Vec3{x, y, z}) < 0) x0 = std::min(x0, x), x1 = std::max(x1, x);
    if (x0 > x1) continue;
    const Vec3 hit{0.5 * (x0 + x1), y, z}, n3{0.0, by, bz};
    return crossing(f, hit + 2.0 * n3, hit - 2.0 * n3);
  }
  return outline[corner];
}

// Me: the lowest point of the symphysis on its mid-sagittal line x.
template <class F>
Vec3 menton(const F& f, double x) {
  Vec3 best{0, 0, kFar};
  for (double y = -82; y <= -60; y += 0.1) {
    const Vec3 q = crossing(f, Vec3{x, y, -100}, Vec3{x, y, -60});
    if (f(Vec3{x, y, -60}) < 0 && q[2] < best[2]) best = q;
  }
  return best;
}

// Pog: the most anterior point of the chin, between Me and the alveolar region.
template <class F>
Vec3 pogonion(const F& f, double x, const Vec3& me) {
  Vec3 pog{0, kFar, 0};
  for (double z = me[2] + 1.0; z <= me[2] + 20.0; z += 0.1) {
    if (f(Vec3{x, -70, z}) >= 0) continue;
    const Vec3 q = crossing(f, Vec3{x, -100, z}, Vec3{x, -70, z});
    if (q[1] < pog[1]) pog = q;
  }
  return pog;
}

}  // namespace

LandmarkSet Anatomy::landmarks() const {
  LandmarkSet out;
  auto f = [this](const Vec3& q) { return mandible_bone(q); };
  for (int si = 0; si < 2; ++si) {
    const SideModel& m = side_[si];
    const std::string suf = si == 0 ? "_L" : "_R";
    // Co, Cr: most superior surface point of the condylar head / coronoid process.
    out.set("Co" + suf, highest_point(f, m.head_center, 9.0, 7.0));
    out.set("Cr" + suf, highest_point(f, m.to_h(m.coronoid_fu.x, m.coronoid_fu.y - 4.0, 0.0), 5.0, 7.0));
    // Go: on the outline of the ramus plate and the body's lower border.
    std::vector<Vec3> outline;
    for (const auto& q : m.polygon) outline.push_back(m.to_h(q.x, q.y, 0.0));
    const auto& arc = arch_[si];
    const auto& tt = arch_t_[si];
    for (std::size_t i = 0; i < arc.size(); ++i)
      if (tt[i] >= 0.35) outline.push_back({arc[i].x, arc[i].y, z_lower(tt[i])});
    out.set("Go" + suf, gonion(f, outline));
  }
  const double x = chin_center_[0];
  const Vec3 me = menton(f, x);
  out.set("Me", me);
  out.set("Pog", pogonion(f, x, me));
  return out;
}

}  // namespace ms::phantom
