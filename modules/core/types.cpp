#include "core/types.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace ms {

Vec3 Geometry::index_to_lps(double i, double j, double k) const {
  const double s[3] = {i * spacing[0], j * spacing[1], k * spacing[2]};
  Vec3 p = origin;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) p[r] += direction[3 * r + c] * s[c];
  return p;
}

Vec3 Geometry::lps_to_index(const Vec3& p) const {
  // direction is orthonormal for every grid we accept, so its inverse is its transpose.
  const Vec3 d = p - origin;
  Vec3 idx{0, 0, 0};
  for (int c = 0; c < 3; ++c) {
    double s = 0;
    for (int r = 0; r < 3; ++r) s += direction[3 * r + c] * d[r];
    idx[c] = s / spacing[c];
  }
  return idx;
}

double interpolate(const Volume& volume, const Vec3& lps) { return interpolate(volume.geom, volume.hu.data(), lps); }

double interpolate(const Geometry& g, const float* hu, const Vec3& lps) {
  const Vec3 q = g.lps_to_index(lps);
  std::size_t i0[3];
  double f[3];
  for (int a = 0; a < 3; ++a) {
    const double last = static_cast<double>(g.size[a]) - 1.0;
    if (g.size[a] < 2 || !(q[a] >= 0.0) || q[a] > last) return std::numeric_limits<double>::quiet_NaN();
    const double fl = std::min(std::floor(q[a]), last - 1.0);
    i0[a] = static_cast<std::size_t>(fl);
    f[a] = q[a] - fl;
  }
  double v = 0;
  for (int dz = 0; dz < 2; ++dz)
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) {
        const double w = (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]);
        if (w > 0) v += w * hu[g.linear(i0[0] + dx, i0[1] + dy, i0[2] + dz)];
      }
  return v;
}

bool Geometry::same_grid(const Geometry& o, double tol) const {
  if (size != o.size) return false;
  for (int a = 0; a < 3; ++a) {
    if (std::abs(spacing[a] - o.spacing[a]) > tol) return false;
    if (std::abs(origin[a] - o.origin[a]) > tol * 10) return false;
  }
  for (int a = 0; a < 9; ++a)
    if (std::abs(direction[a] - o.direction[a]) > tol) return false;
  return true;
}

std::size_t Mask::count() const {
  std::size_t n = 0;
  for (auto v : data) n += v != 0;
  return n;
}

double dice(const Mask& a, const Mask& b) {
  std::size_t inter = 0, na = 0, nb = 0;
  for (std::size_t i = 0; i < a.data.size() && i < b.data.size(); ++i) {
    na += a.data[i] != 0;
    nb += b.data[i] != 0;
    inter += a.data[i] && b.data[i];
  }
  return na + nb ? 2.0 * static_cast<double>(inter) / static_cast<double>(na + nb) : 1.0;
}

double Plane::signed_distance(const Vec3& p) const { return dot(normal, p - point); }

Vec3 Plane::reflect(const Vec3& p) const { return p - (2.0 * signed_distance(p)) * normal; }

std::string mirror_label(const std::string& name) {
  auto ends = [&](const char* s) {
    const std::string suf(s);
    return name.size() >= suf.size() && name.compare(name.size() - suf.size(), suf.size(), suf) == 0;
  };
  if (ends("_L")) return name.substr(0, name.size() - 2) + "_R";
  if (ends("_R")) return name.substr(0, name.size() - 2) + "_L";
  return name;
}

const Vec3* LandmarkSet::find(const std::string& name) const {
  for (const auto& [n, p] : points)
    if (n == name) return &p;
  return nullptr;
}

void LandmarkSet::set(const std::string& name, const Vec3& p) {
  for (auto& [n, q] : points)
    if (n == name) {
      q = p;
      return;
    }
  points.emplace_back(name, p);
}

double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }
Vec3 normalized(const Vec3& a) {
  const double n = norm(a);
  if (n == 0) throw std::invalid_argument("normalized: zero vector");
  return (1.0 / n) * a;
}
double distance(const Vec3& a, const Vec3& b) { return norm(a - b); }

}  // namespace ms
