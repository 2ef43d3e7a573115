#include "asymmetry/measures.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

#include "geometry/mesh_geometry.h"

namespace ms::asymmetry {

Regions assign_regions(const Mesh& mesh, const LandmarkSet& lm) {
  Regions r;
  std::vector<int> seeds, seed_region;
  auto add = [&](const std::string& region, const Vec3* p) {
    if (!p) return;
    auto it = std::find(r.names.begin(), r.names.end(), region);
    int id;
    if (it == r.names.end()) {
      r.names.push_back(region);
      id = static_cast<int>(r.names.size()) - 1;
    } else {
      id = static_cast<int>(it - r.names.begin());
    }
    seeds.push_back(geometry::nearest_vertex(mesh, *p));
    seed_region.push_back(id);
  };
  for (const char* s : {"L", "R"}) {
    const std::string suf = std::string("_") + s;
    const Vec3 *co = lm.find("Co" + suf), *cr = lm.find("Cr" + suf), *go = lm.find("Go" + suf), *me = lm.find("Me");
    add("condyle" + suf, co);
    add("coronoid" + suf, cr);
    add("angle" + suf, go);
    if (co && go) {
      const Vec3 mid = 0.5 * (*co + *go);
      add("ramus" + suf, &mid);
    }
    if (go && me) {
      const Vec3 mid = 0.5 * (*go + *me);
      add("body" + suf, &mid);
    }
  }
  add("symphysis", lm.find("Me"));
  add("symphysis", lm.find("Pog"));
  const auto owner = geometry::geodesic_voronoi(mesh, seeds);
  r.label.resize(owner.size());
  for (std::size_t i = 0; i < owner.size(); ++i) r.label[i] = owner[i] >= 0 ? seed_region[owner[i]] : -1;
  return r;
}

std::vector<double> vertex_areas(const Mesh& mesh) {
  std::vector<double> a(mesh.vertices.size(), 0.0);
  const auto fa = geometry::face_areas(mesh);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (int k = 0; k < 3; ++k) a[mesh.faces[f][k]] += fa[f] / 3.0;
  return a;
}

DistanceStats distance_stats(const std::vector<double>& d, const std::vector<double>& w) {
  DistanceStats s;
  double W = 0;
  std::vector<std::pair<double, double>> absw;
  for (std::size_t i = 0; i < d.size(); ++i) {
    const double a = std::abs(d[i]);
    W += w[i];
    s.mean_abs += w[i] * a;
    s.signed_mean += w[i] * d[i];
    s.rms += w[i] * d[i] * d[i];
    s.max = std::max(s.max, a);
    s.max_outward = std::max(s.max_outward, d[i]);
    s.max_inward = std::max(s.max_inward, -d[i]);
    if (a > 1.0) s.pct_area_over_1mm += w[i];
    if (a > 2.0) s.pct_area_over_2mm += w[i];
    absw.emplace_back(a, w[i]);
  }
  if (W <= 0) return DistanceStats{};
  s.mean_abs /= W;
  s.signed_mean /= W;
  s.rms = std::sqrt(s.rms / W);
  s.pct_area_over_1mm *= 100.0 / W;
  s.pct_area_over_2mm *= 100.0 / W;
  std::sort(absw.begin(), absw.end());
  double acc = 0;
  for (const auto& [a, ww] : absw) {
    acc += ww;
    if (acc >= 0.95 * W) {
      s.p95 = a;
      break;
    }
  }
  return s;
}

MirrorResult mirror_distance(const Mesh& mesh, const Plane& plane, const Regions& regions, const LandmarkSet* landmarks) {
  MirrorResult r;
  const geometry::ClosestPointIndex index(mesh);
  const auto fn = geometry::face_normals(mesh);
  const std::size_t n = mesh.vertices.size();
  r.per_vertex.resize(n);
  // d(v) = signed distance of the reflection of v to the surface: the reflected
  // surface at v lies inside this side where this side bulges (d > 0). The
  // closest point is v's mirror point σ(v).
  std::vector<geometry::ClosestHit> hit(n);
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < n; ++i)
    r.per_vertex[i] = geometry::signed_distance(index, fn, plane.reflect(mesh.vertices[i]), &hit[i]);
  r.at_mirror_point.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto& f = mesh.faces[static_cast<std::size_t>(hit[i].face)];
    r.at_mirror_point[i] = hit[i].bary[0] * r.per_vertex[f[0]] + hit[i].bary[1] * r.per_vertex[f[1]] +
                           hit[i].bary[2] * r.per_vertex[f[2]];
  }
  const auto w = vertex_areas(mesh);
  r.overall = distance_stats(r.per_vertex, w);
  for (std::size_t k = 0; k < regions.names.size(); ++k) {
    std::vector<double> d, ww;
    for (std::size_t i = 0; i < r.per_vertex.size(); ++i)
      if (regions.label[i] == static_cast<int>(k)) d.push_back(r.per_vertex[i]), ww.push_back(w[i]);
    r.regions[regions.names[k]] = distance_stats(d, ww);
  }
  if (landmarks)
    for (const auto& [name, p] : landmarks->points) {
      const int v = geometry::nearest_vertex(mesh, p);
      if (v >= 0) r.at_landmarks[name] = r.per_vertex[static_cast<std::size_t>(v)];
    }
  return r;
}

std::map<std::string, double> regional_means(const std::vector<double>& values, const std::vector<double>& areas,
                                             const Regions& regions) {
  std::map<std::string, double> out;
  std::vector<double> s(regions.names.size(), 0.0), w(regions.names.size(), 0.0);
  for (std::size_t i = 0; i < values.size() && i < regions.label.size(); ++i)
    if (regions.label[i] >= 0) s[regions.label[i]] += areas[i] * values[i], w[regions.label[i]] += areas[i];
  for (std::size_t k = 0; k < regions.names.size(); ++k) out[regions.names[k]] = w[k] > 0 ? s[k] / w[k] : 0.0;
  return out;
}

namespace {
// e(v) / share_mm clamped to [-1, 1], e = half the difference of the signed
// mirror distances at v and at its mirror point.
std::vector<double> side_weights(const std::vector<double>& pair_map, const MirrorResult& mirror, double share_mm,
                                 const char* who) {
  if (pair_map.size() != mirror.per_vertex.size() || mirror.at_mirror_point.size() != mirror.per_vertex.size())
    throw std::invalid_argument(std::string(who) + ": one value per vertex in the map and the mirror distance");
  if (!(share_mm > 0)) throw std::invalid_argument(std::string(who) + ": share_mm must be > 0");
  std::vector<double> w(pair_map.size());
  for (std::size_t i = 0; i < w.size(); ++i)
    w[i] = std::clamp(0.5 * (mirror.per_vertex[i] - mirror.at_mirror_point[i]) / share_mm, -1.0, 1.0);
  return w;
}
}  // namespace

std::vector<double> sided_map(const std::vector<double>& pair_map, const MirrorResult& mirror, double share_mm) {
  std::vector<double> out = side_weights(pair_map, mirror, share_mm, "sided_map");
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = (1.0 + out[i]) * pair_map[i];
  return out;
}

std::vector<double> lateral_map(const std::vector<double>& pair_map, const MirrorResult& mirror, double share_mm) {
  std::vector<double> out = side_weights(pair_map, mirror, share_mm, "lateral_map");
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = 2.0 * out[i] * pair_map[i];
  return out;
}

std::string largest_region(const std::map<std::string, double>& regional) {
  std::string best;
  double top = -std::numeric_limits<double>::infinity();
  for (const auto& [name, v] : regional)
    if (v > top) top = v, best = name;
  return best;
}

std::map<std::string, Bilateral> bilateral_measures(const LandmarkSet& lm, const Plane& plane) {
  std::map<std::string, Bilateral> out;
  auto pair = [&](const std::string& name, auto f) {
    double L, R;
    if (f("_L", L) && f("_R", R)) out[name] = {L, R, L - R, R != 0 ? L / R : 0.0};
  };
  auto dist = [&](const char* a, const char* b) {
    return [&lm, a, b](const std::string& s, double& v) {
      const std::string na = std::string(a) + (std::string(a) == "Me" ? "" : s);
      const std::string nb = std::string(b) + (std::string(b) == "Me" ? "" : s);
      const Vec3 *pa = lm.find(na), *pb = lm.find(nb);
      if (!pa || !pb) return false;
      v = distance(*pa, *pb);
      return true;
    };
  };
  pair("ramus_height_mm", dist("Co", "Go"));
  pair("body_length_mm", dist("Go", "Me"));
  pair("gonial_angle_deg", [&](const std::string& s, double& v) {
    const Vec3 *co = lm.find("Co" + s), *go = lm.find("Go" + s), *me = lm.find("Me");
    if (!co || !go || !me) return false;
    const Vec3 a = *co - *go, b = *me - *go;
    v = std::acos(std::clamp(dot(a, b) / (norm(a) * norm(b)), -1.0, 1.0)) * 180.0 / 3.14159265358979323846;
    return true;
  });
  auto to_plane = [&](const char* n) {
    return [&lm, &plane, n](const std::string& s, double& v) {
      const Vec3* p = lm.find(std::string(n) + s);
      if (!p) return false;
      v = std::abs(plane.signed_distance(*p));
      return true;
    };
  };
  pair("condyle_to_plane_mm", to_plane("Co"));
  pair("gonion_to_plane_mm", to_plane("Go"));
  return out;
}

}  // namespace ms::asymmetry
