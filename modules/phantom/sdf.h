// Signed-distance primitives for the phantom's implicit anatomy (mm).
// Negative inside. Some are bounds rather than exact distances away from the
// surface (noted); all are exact or close to exact near their zero set, which
// is what partial-volume rasterisation needs.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/types.h"

namespace ms::phantom::sdf {

inline double clamp01(double v) { return std::min(1.0, std::max(0.0, v)); }

// Polynomial smooth minimum (union) with blend radius k (mm).
inline double smin(double a, double b, double k) {
  if (k <= 0) return std::min(a, b);
  const double h = clamp01(0.5 + 0.5 * (b - a) / k);
  return b + (a - b) * h - k * h * (1.0 - h);
}

// Ellipsoid with half-axes r centred at the origin (approximate away from surface).
inline double ellipsoid(const Vec3& p, const Vec3& r) {
  const double k0 = std::sqrt(p[0] * p[0] / (r[0] * r[0]) + p[1] * p[1] / (r[1] * r[1]) + p[2] * p[2] / (r[2] * r[2]));
  const double k1 = std::sqrt(p[0] * p[0] / (r[0] * r[0] * r[0] * r[0]) + p[1] * p[1] / (r[1] * r[1] * r[1] * r[1]) +
                              p[2] * p[2] / (r[2] * r[2] * r[2] * r[2]));
  if (k1 < 1e-12) return -std::min({r[0], r[1], r[2]});
  return k0 * (k0 - 1.0) / k1;
}

// Capsule: segment a-b with radius r.
inline double capsule(const Vec3& p, const Vec3& a, const Vec3& b, double r) {
  const Vec3 pa = p - a, ba = b - a;
  const double h = clamp01(dot(pa, ba) / dot(ba, ba));
  return norm(pa - h * ba) - r;
}

// Axis-aligned box with half-extents h, edges rounded by r (r inside h).
inline double round_box(const Vec3& p, const Vec3& h, double r) {
  const Vec3 q{std::abs(p[0]) - h[0] + r, std::abs(p[1]) - h[1] + r, std::abs(p[2]) - h[2] + r};
  const Vec3 qp{std::max(q[0], 0.0), std::max(q[1], 0.0), std::max(q[2], 0.0)};
  return norm(qp) + std::min(std::max({q[0], q[1], q[2]}), 0.0) - r;
}

// Combines an in-plane distance d2 with an out-of-plane half-extent test
// (extrusion / generalised box): w = (d2, dz).
inline double extrude(double d2, double dz) {
  const double a = std::max(d2, 0.0), b = std::max(dz, 0.0);
  return std::sqrt(a * a + b * b) + std::min(std::max(d2, dz), 0.0);
}

struct P2 {
  double x, y;
};

// Exact signed distance to a simple closed polygon (any orientation).
inline double polygon(const std::vector<P2>& v, P2 p) {
  double d = (p.x - v[0].x) * (p.x - v[0].x) + (p.y - v[0].y) * (p.y - v[0].y);
  double s = 1.0;
  const std::size_t n = v.size();
  for (std::size_t i = 0, j = n - 1; i < n; j = i, ++i) {
    const P2 e{v[j].x - v[i].x, v[j].y - v[i].y};
    const P2 w{p.x - v[i].x, p.y - v[i].y};
    const double t = clamp01((w.x * e.x + w.y * e.y) / (e.x * e.x + e.y * e.y));
    const P2 b{w.x - e.x * t, w.y - e.y * t};
    d = std::min(d, b.x * b.x + b.y * b.y);
    const bool c1 = p.y >= v[i].y, c2 = p.y < v[j].y, c3 = e.x * w.y > e.y * w.x;
    if ((c1 && c2 && c3) || (!c1 && !c2 && !c3)) s = -s;
  }
  return s * std::sqrt(d);
}

}  // namespace ms::phantom::sdf
