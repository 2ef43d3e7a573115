#include "asymmetry/saf.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>

#include "asymmetry/harmonic.h"
#include "geometry/mesh_geometry.h"

namespace ms::asymmetry {
namespace {
constexpr double kPi = 3.14159265358979323846;
}

double wrap_angle(double a) {
  a = std::fmod(a + kPi, 2 * kPi);
  if (a <= 0) a += 2 * kPi;
  return a - kPi;
}

const std::vector<Configuration>& default_configurations() {
  static const std::vector<Configuration> c = {
      {"Co-Me|Cr-Go", "Co_L", "Me", "Cr_L", "Go_L"},
      {"Co-Go|Cr-Pog", "Co_L", "Go_L", "Cr_L", "Pog"},
      {"Go-Me|Co-Cr", "Go_L", "Me", "Co_L", "Cr_L"},
      {"Co-Pog|Go-Me", "Co_L", "Pog", "Go_L", "Me"},
  };
  return c;
}

Configuration mirrored(const Configuration& c) {
  return {c.name, mirror_label(c.a), mirror_label(c.b), mirror_label(c.c), mirror_label(c.d)};
}

std::vector<double> signed_angle_field(const Mesh& mesh, const std::vector<Vec3>& g1, const std::vector<Vec3>& g2,
                                       double ratio) {
  const auto fn = geometry::face_normals(mesh);
  auto median_norm = [](const std::vector<Vec3>& g) {
    std::vector<double> n;
    n.reserve(g.size());
    for (const auto& v : g) n.push_back(norm(v));
    std::nth_element(n.begin(), n.begin() + n.size() / 2, n.end());
    return n[n.size() / 2];
  };
  const double t1 = ratio * median_norm(g1), t2 = ratio * median_norm(g2);
  std::vector<double> th(mesh.faces.size(), std::nan(""));
  for (std::size_t f = 0; f < th.size(); ++f) {
    if (norm(g1[f]) <= t1 || norm(g2[f]) <= t2 || norm(fn[f]) == 0) continue;
    th[f] = std::atan2(dot(fn[f], cross(g1[f], g2[f])), dot(g1[f], g2[f]));
  }
  return th;
}

LandmarkSet saf_anchors(const LandmarkSet& detected, const LandmarkSet& reference, bool use_reference) {
  LandmarkSet out;
  for (const auto& [name, p] : detected.points) {
    const Vec3* q = use_reference ? reference.find(name) : nullptr;
    out.set(name, q ? *q : p);
  }
  return out;
}

namespace {

// The SAF on a mesh already cut along the disks' circles (anchors on its
// surface, disk radius with the tolerance that takes in the cut's vertices).
SafResult saf_on(const Mesh& mesh, const LandmarkSet& anchors, const Plane& plane, const SafOptions& opt) {
  SafResult r;
  const std::size_t nf = mesh.faces.size();
  // The closest-point tree and the Laplacian are independent: built side by side.
  std::unique_ptr<geometry::ClosestPointIndex> index_ptr;
  std::unique_ptr<HarmonicFieldSolver> solver_ptr;
#pragma omp parallel sections
  {
#pragma omp section
    index_ptr = std::make_unique<geometry::ClosestPointIndex>(mesh);
#pragma omp section
    solver_ptr = std::make_unique<HarmonicFieldSolver>(mesh, opt.disk_radius_mm);
  }
  const geometry::ClosestPointIndex& index = *index_ptr;
  HarmonicFieldSolver& solver = *solver_ptr;
  const LandmarkSet& lm = anchors;  // on the surface already (compute_saf projected them)
  r.disk_centres = lm;
  std::map<std::pair<std::string, std::string>, std::vector<Vec3>> grads;
  auto gradient = [&](const std::string& a, const std::string& b) -> const std::vector<Vec3>& {
    auto& g = grads[{a, b}];
    if (g.empty()) g = face_gradients(mesh, solver.solve(*lm.find(a), *lm.find(b)));
    return g;
  };
  auto theta = [&](const Configuration& c) {
    return signed_angle_field(mesh, gradient(c.a, c.b), gradient(c.c, c.d), opt.min_gradient_ratio);
  };

  // A configuration is computable when it and its mirror have all their landmarks.
  auto complete = [&](const Configuration& c) {
    const Configuration m = mirrored(c);
    for (const auto* n : {&c.a, &c.b, &c.c, &c.d, &m.a, &m.b, &m.c, &m.d})
      if (!lm.has(*n)) return false;
    return true;
  };
  std::unique_ptr<SurfaceSmoother> smoother;
  {
    std::vector<std::pair<Vec3, Vec3>> pairs;
    for (const auto& c : opt.configurations)
      if (complete(c))
        for (const auto& k : {c, mirrored(c)})
          for (const auto& [x, y] : {std::make_pair(k.a, k.b), std::make_pair(k.c, k.d)})
            pairs.emplace_back(*lm.find(x), *lm.find(y));
    // The two factorisations (harmonic fields, heat smoother) are independent
    // and single-threaded: side by side.
#pragma omp parallel sections
    {
#pragma omp section
      solver.prepare(pairs);
#pragma omp section
      if (opt.smoothing_mm > 0) smoother = std::make_unique<SurfaceSmoother>(mesh, opt.smoothing_mm);
    }
  }
  {
    // Every field the configurations need, on the shared factorisation in
    // parallel; anything off it (overlapping disks, a failed shared
    // factorisation) is left to gradient(), serially.
    std::vector<std::pair<std::string, std::string>> need;
    for (const auto& c : opt.configurations)
      if (complete(c))
        for (const auto& k : {c, mirrored(c)})
          for (const auto& ab : {std::make_pair(k.a, k.b), std::make_pair(k.c, k.d)})
            if (std::find(need.begin(), need.end(), ab) == need.end()) need.push_back(ab);
    std::vector<std::vector<Vec3>> g(need.size());
#pragma omp parallel for schedule(dynamic)
    for (int i = 0; i < static_cast<int>(need.size()); ++i) {
      std::vector<double> u;
      try {
        if (solver.solve_prepared(*lm.find(need[static_cast<std::size_t>(i)].first), *lm.find(need[static_cast<std::size_t>(i)].second), u))
          g[static_cast<std::size_t>(i)] = face_gradients(mesh, u);
      } catch (const std::exception&) {
        // gradient() reports it
      }
    }
    for (std::size_t i = 0; i < need.size(); ++i)
      if (!g[i].empty()) grads[need[i]] = std::move(g[i]);
  }
  const std::size_t nv = mesh.vertices.size();
  const auto area = geometry::face_areas(mesh);
  // Mirror correspondence. Smoothed: σ(v) = closest surface point to the
  // reflected vertex (face + barycentric coordinates). Per face: σ(f) = face
  // containing the closest surface point to the reflected centroid.
  std::vector<geometry::ClosestHit> vertex_mirror;
  std::vector<int> sigma;
  if (smoother) {
    vertex_mirror.resize(nv);
#pragma omp parallel for schedule(static)
    for (long v = 0; v < static_cast<long>(nv); ++v)
      vertex_mirror[static_cast<std::size_t>(v)] = index.closest(plane.reflect(mesh.vertices[static_cast<std::size_t>(v)]));
  } else {
    sigma.resize(nf);
#pragma omp parallel for schedule(static)
    for (long fl = 0; fl < static_cast<long>(nf); ++fl) {
      const std::size_t f = static_cast<std::size_t>(fl);
      const auto& t = mesh.faces[f];
      const Vec3 c = (1.0 / 3.0) * (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]);
      sigma[f] = index.closest(plane.reflect(c)).face;
    }
  }
  // Sums of a_k for the SAF map: per vertex (smoothed) or per face.
  std::vector<double> map_sum(smoother ? nv : nf, 0.0);
  std::vector<int> map_cnt(map_sum.size(), 0);
  double score_sum = 0, free_sum = 0;
  int used = 0;
  for (const auto& c : opt.configurations) {
    const Configuration m = mirrored(c);
    if (!complete(c)) {
      r.skipped.push_back(c.name);
      continue;
    }
    std::vector<double> tc, tm;
    try {
      tc = theta(c);
      tm = theta(m);
    } catch (const std::exception&) {
      r.skipped.push_back(c.name);
      continue;
    }
    if (opt.keep_fields && !smoother) {  // the fields the comparison uses: raw per face
      r.fields.push_back({c.name, false, c, tc});
      r.fields.push_back({c.name, true, m, tm});
    }
    double num = 0, den = 0;
    if (smoother) {
      // Smoothed fields per vertex, compared at the mirror point with
      // barycentric interpolation (continuous, so no ties between faces).
      auto smoothed = [&](const std::vector<double>& th) {
        std::vector<double> w(nf, 0.0);
        for (std::size_t f = 0; f < nf; ++f) w[f] = std::isnan(th[f]) ? 0.0 : area[f];
        return smoother->smooth_face_angles(th, w);
      };
      std::vector<double> sc, sm;
#pragma omp parallel sections
      {
#pragma omp section
        sc = smoothed(tc);
#pragma omp section
        sm = smoothed(tm);
      }
      if (opt.keep_fields) {  // the fields the comparison uses: smoothed per vertex
        r.fields.push_back({c.name, false, c, sc});
        r.fields.push_back({c.name, true, m, sm});
      }
      auto at_mirror = [&](const std::vector<double>& s, std::size_t v) {
        const auto& h = vertex_mirror[v];
        const auto& t = mesh.faces[h.face];
        double sn = 0, cs = 0;
        for (int k = 0; k < 3; ++k) {
          if (std::isnan(s[t[k]])) return std::nan("");
          sn += h.bary[k] * std::sin(s[t[k]]);
          cs += h.bary[k] * std::cos(s[t[k]]);
        }
        return std::atan2(sn, cs);
      };
      const auto& va = smoother->vertex_areas();
      for (std::size_t v = 0; v < sc.size(); ++v) {
        const double r1 = wrap_angle(sc[v] + at_mirror(sm, v)), r2 = wrap_angle(sm[v] + at_mirror(sc, v));
        if (std::isnan(r1) || std::isnan(r2)) continue;
        const double a = 0.5 * (std::abs(r1) + std::abs(r2));
        num += va[v] * a;
        den += va[v];
        map_sum[v] += a;
        map_cnt[v] += 1;
      }
    } else {
      for (std::size_t f = 0; f < nf; ++f) {
        const std::size_t g = static_cast<std::size_t>(sigma[f]);
        if (std::isnan(tc[f]) || std::isnan(tm[f]) || std::isnan(tc[g]) || std::isnan(tm[g])) continue;
        const double a = 0.5 * (std::abs(wrap_angle(tc[f] + tm[g])) + std::abs(wrap_angle(tm[f] + tc[g])));
        num += area[f] * a;
        den += area[f];
        map_sum[f] += a;
        map_cnt[f] += 1;
      }
    }
    const double s = den > 0 ? num / den : 0.0;
    r.per_configuration[c.name] = s;
    score_sum += s;
    // Correspondence-free: circular W1 between the area-weighted distributions
    // of θ_C and -θ_σ(C) (360 bins).
    const int B = 360;
    std::vector<double> h1(B, 0.0), h2(B, 0.0);
    double w1 = 0, w2 = 0;
    auto bin = [&](double a) { return std::min(B - 1, static_cast<int>((a + kPi) / (2 * kPi) * B)); };
    for (std::size_t f = 0; f < nf; ++f) {
      if (!std::isnan(tc[f])) h1[bin(tc[f])] += area[f], w1 += area[f];
      if (!std::isnan(tm[f])) h2[bin(wrap_angle(-tm[f]))] += area[f], w2 += area[f];
    }
    std::vector<double> diff(B);
    double c1 = 0, c2 = 0;
    for (int b = 0; b < B; ++b) {
      c1 += h1[b] / w1;
      c2 += h2[b] / w2;
      diff[b] = c1 - c2;
    }
    std::vector<double> sorted = diff;
    std::nth_element(sorted.begin(), sorted.begin() + B / 2, sorted.end());
    const double med = sorted[B / 2];
    double w = 0;
    for (int b = 0; b < B; ++b) w += std::abs(diff[b] - med) * (2 * kPi / B);
    free_sum += w;
    ++used;
  }
  r.factorisations = solver.factorisations();
  if (used == 0) return r;
  r.score = score_sum / used;
  r.correspondence_free = free_sum / used;
  // SAF map: mean over configurations per vertex; per face, then the
  // area-weighted mean of the incident faces.
  r.per_vertex.assign(nv, 0.0);
  if (smoother) {
    for (std::size_t v = 0; v < nv; ++v)
      if (map_cnt[v] > 0) r.per_vertex[v] = map_sum[v] / map_cnt[v];
    return r;
  }
  std::vector<double> vw(nv, 0.0);
  for (std::size_t f = 0; f < nf; ++f) {
    if (map_cnt[f] == 0) continue;
    const double a = map_sum[f] / map_cnt[f];
    for (int k = 0; k < 3; ++k) {
      r.per_vertex[mesh.faces[f][k]] += area[f] * a;
      vw[mesh.faces[f][k]] += area[f];
    }
  }
  for (std::size_t v = 0; v < nv; ++v)
    if (vw[v] > 0) r.per_vertex[v] /= vw[v];
  return r;
}

}  // namespace

SafResult compute_saf(const Mesh& mesh, const LandmarkSet& anchors, const Plane& plane, const SafOptions& opt) {
  // Disk centres: the anchors projected onto the surface (the symmetric
  // reference configuration lies off the surface where the mandible is
  // asymmetric). The mesh is then cut along the disks' circles: a disk of the
  // vertices that happen to lie within 2 mm gains or loses one of its ~12
  // with the triangulation, and its size (the field's capacity) jumps with
  // it — 0.1 mm of radius moved a score by 15-30 % (docs/method.md).
  LandmarkSet centres;
  std::vector<Vec3> points;
  for (const auto& [name, p] : anchors.points) {
    centres.set(name, geometry::closest_point_brute_force(mesh, p));
    points.push_back(*centres.find(name));
  }
  std::vector<int> parent;
  const Mesh cut = geometry::cut_along_spheres(mesh, points, opt.disk_radius_mm, &parent);
  SafOptions o = opt;
  o.disk_radius_mm = opt.disk_radius_mm + 1e-6;  // the cut's vertices lie on the circle
  SafResult r = saf_on(cut, centres, plane, o);
  // Back to the input mesh: its vertices are the cut mesh's first ones; a
  // face takes the value of its largest piece.
  const std::size_t nv = mesh.vertices.size(), nf = mesh.faces.size();
  if (r.per_vertex.size() > nv) r.per_vertex.resize(nv);
  const bool per_face = opt.smoothing_mm <= 0;
  std::vector<int> largest(nf, -1);
  if (per_face && !r.fields.empty()) {
    const auto area = geometry::face_areas(cut);
    for (std::size_t f = 0; f < cut.faces.size(); ++f) {
      int& l = largest[static_cast<std::size_t>(parent[f])];
      if (l < 0 || area[f] > area[static_cast<std::size_t>(l)]) l = static_cast<int>(f);
    }
  }
  for (auto& field : r.fields) {
    if (!per_face) {
      field.theta.resize(nv);
      continue;
    }
    std::vector<double> t(nf);
    for (std::size_t f = 0; f < nf; ++f) t[f] = field.theta[static_cast<std::size_t>(largest[f])];
    field.theta = std::move(t);
  }
  return r;
}

}  // namespace ms::asymmetry
