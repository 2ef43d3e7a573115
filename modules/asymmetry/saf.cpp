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

// The harmonic field u_ab (0 on the disk at a, 1 on the disk at b) is named
// by its two landmarks.
using FieldKey = std::pair<std::string, std::string>;

// A configuration is computable when it and its mirror have all their landmarks.
bool complete(const Configuration& c, const LandmarkSet& lm) {
  const Configuration m = mirrored(c);
  for (const auto* n : {&c.a, &c.b, &c.c, &c.d, &m.a, &m.b, &m.c, &m.d})
    if (!lm.has(*n)) return false;
  return true;
}

// The fields the computable configurations compare, C then σ(C), each as
// ((a, b), (c, d)); a field shared by two configurations appears twice.
std::vector<FieldKey> fields_of_configurations(const std::vector<Configuration>& configurations,
                                               const LandmarkSet& lm) {
  std::vector<FieldKey> out;
  for (const auto& c : configurations)
    if (complete(c, lm))
      for (const auto& k : {c, mirrored(c)})
        for (const auto& ab : {std::make_pair(k.a, k.b), std::make_pair(k.c, k.d)}) out.push_back(ab);
  return out;
}

std::vector<FieldKey> distinct(const std::vector<FieldKey>& keys) {
  std::vector<FieldKey> out;
  for (const auto& k : keys)
    if (std::find(out.begin(), out.end(), k) == out.end()) out.push_back(k);
  return out;
}

// The closest-point tree (mirror correspondence) and the cotangent Laplacian
// (harmonic fields) are independent: built side by side.
struct SurfaceOperators {
  std::unique_ptr<geometry::ClosestPointIndex> index;
  std::unique_ptr<HarmonicFieldSolver> solver;
};

SurfaceOperators build_index_and_laplacian(const Mesh& mesh, double disk_radius_mm) {
  SurfaceOperators ops;
#pragma omp parallel sections
  {
#pragma omp section
    ops.index = std::make_unique<geometry::ClosestPointIndex>(mesh);
#pragma omp section
    ops.solver = std::make_unique<HarmonicFieldSolver>(mesh, disk_radius_mm);
  }
  return ops;
}

// One factorisation serves every constraint set (HarmonicFieldSolver::prepare);
// the heat smoother's (σ > 0) is the other. Both are single-threaded and
// independent: side by side. Returns the smoother (null when σ = 0).
std::unique_ptr<SurfaceSmoother> prepare_factorisations(HarmonicFieldSolver& solver, const Mesh& mesh,
                                                        const std::vector<FieldKey>& fields,
                                                        const LandmarkSet& lm, double smoothing_mm) {
  std::vector<std::pair<Vec3, Vec3>> pairs;
  for (const auto& [a, b] : fields) pairs.emplace_back(*lm.find(a), *lm.find(b));
  std::unique_ptr<SurfaceSmoother> smoother;
#pragma omp parallel sections
  {
#pragma omp section
    solver.prepare(pairs);
#pragma omp section
    if (smoothing_mm > 0) smoother = std::make_unique<SurfaceSmoother>(mesh, smoothing_mm);
  }
  return smoother;
}

// The per-face gradients ∇u_ab, each solved once.
class FieldGradients {
 public:
  FieldGradients(const Mesh& mesh, HarmonicFieldSolver& solver, const LandmarkSet& lm)
      : mesh_(mesh), solver_(solver), lm_(lm) {}

  // Every field in `need` on the shared factorisation, in parallel; anything
  // off it (overlapping disks, a failed shared factorisation) is left to
  // get(), serially.
  void solve_prepared(const std::vector<FieldKey>& need) {
    std::vector<std::vector<Vec3>> g(need.size());
#pragma omp parallel for schedule(dynamic)
    for (int i = 0; i < static_cast<int>(need.size()); ++i) {
      const FieldKey& ab = need[static_cast<std::size_t>(i)];
      std::vector<double> u;
      try {
        if (solver_.solve_prepared(*lm_.find(ab.first), *lm_.find(ab.second), u))
          g[static_cast<std::size_t>(i)] = face_gradients(mesh_, u);
      } catch (const std::exception&) {
        // get() reports it
      }
    }
    for (std::size_t i = 0; i < need.size(); ++i)
      if (!g[i].empty()) grads_[need[i]] = std::move(g[i]);
  }

  const std::vector<Vec3>& get(const std::string& a, const std::string& b) {
    auto& g = grads_[{a, b}];
    if (g.empty()) g = face_gradients(mesh_, solver_.solve(*lm_.find(a), *lm_.find(b)));
    return g;
  }

 private:
  const Mesh& mesh_;
  HarmonicFieldSolver& solver_;
  const LandmarkSet& lm_;
  std::map<FieldKey, std::vector<Vec3>> grads_;
};

// θ_C per face.
std::vector<double> theta(const Mesh& mesh, FieldGradients& gradients, const Configuration& c, double ratio) {
  return signed_angle_field(mesh, gradients.get(c.a, c.b), gradients.get(c.c, c.d), ratio);
}

// Mirror correspondence, smoothed: σ(v) = the closest surface point to the
// reflected vertex (face + barycentric coordinates).
std::vector<geometry::ClosestHit> vertex_mirrors(const Mesh& mesh, const geometry::ClosestPointIndex& index,
                                                 const Plane& plane) {
  const std::size_t nv = mesh.vertices.size();
  std::vector<geometry::ClosestHit> out(nv);
#pragma omp parallel for schedule(static)
  for (long v = 0; v < static_cast<long>(nv); ++v)
    out[static_cast<std::size_t>(v)] = index.closest(plane.reflect(mesh.vertices[static_cast<std::size_t>(v)]));
  return out;
}

// Mirror correspondence per face: σ(f) = the face containing the closest
// surface point to the reflected centroid.
std::vector<int> face_mirrors(const Mesh& mesh, const geometry::ClosestPointIndex& index, const Plane& plane) {
  const std::size_t nf = mesh.faces.size();
  std::vector<int> sigma(nf);
#pragma omp parallel for schedule(static)
  for (long fl = 0; fl < static_cast<long>(nf); ++fl) {
    const std::size_t f = static_cast<std::size_t>(fl);
    const auto& t = mesh.faces[f];
    const Vec3 c = (1.0 / 3.0) * (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]);
    sigma[f] = index.closest(plane.reflect(c)).face;
  }
  return sigma;
}

// Heat-kernel smoothing of θ per vertex (circular mean), masked faces weighted 0.
std::vector<double> smoothed_field(const SurfaceSmoother& smoother, const std::vector<double>& th,
                                   const std::vector<double>& area) {
  std::vector<double> w(th.size(), 0.0);
  for (std::size_t f = 0; f < th.size(); ++f) w[f] = std::isnan(th[f]) ? 0.0 : area[f];
  return smoother.smooth_face_angles(th, w);
}

// θ_C and θ_σ(C) of one configuration.
struct FieldPair {
  std::vector<double> c, m;
};

FieldPair smoothed_fields(const SurfaceSmoother& smoother, const FieldPair& raw, const std::vector<double>& area) {
  FieldPair s;
#pragma omp parallel sections
  {
#pragma omp section
    s.c = smoothed_field(smoother, raw.c, area);
#pragma omp section
    s.m = smoothed_field(smoother, raw.m, area);
  }
  return s;
}

// A smoothed field at a mirror point: barycentric interpolation of the angle
// (continuous, so no ties between faces); NaN when a corner is masked.
double at_mirror(const Mesh& mesh, const std::vector<double>& s, const geometry::ClosestHit& h) {
  const auto& t = mesh.faces[h.face];
  double sn = 0, cs = 0;
  for (int k = 0; k < 3; ++k) {
    if (std::isnan(s[t[k]])) return std::nan("");
    sn += h.bary[k] * std::sin(s[t[k]]);
    cs += h.bary[k] * std::cos(s[t[k]]);
  }
  return std::atan2(sn, cs);
}

// Sums of a_k over the configurations for the SAF map: per vertex (smoothed) or per face.
struct MapSums {
  explicit MapSums(std::size_t n) : sum(n, 0.0), count(n, 0) {}
  std::vector<double> sum;
  std::vector<int> count;
};

// The area-weighted mean of a_k(v) = ½(|wrap(θ̃_C(v) + θ̃_σC(σ(v)))| + |wrap(θ̃_σC(v) + θ̃_C(σ(v)))|).
double mirror_score_per_vertex(const Mesh& mesh, const FieldPair& s, const std::vector<geometry::ClosestHit>& mirror,
                               const std::vector<double>& vertex_area, MapSums& map) {
  double num = 0, den = 0;
  for (std::size_t v = 0; v < s.c.size(); ++v) {
    const double r1 = wrap_angle(s.c[v] + at_mirror(mesh, s.m, mirror[v]));
    const double r2 = wrap_angle(s.m[v] + at_mirror(mesh, s.c, mirror[v]));
    if (std::isnan(r1) || std::isnan(r2)) continue;
    const double a = 0.5 * (std::abs(r1) + std::abs(r2));
    num += vertex_area[v] * a;
    den += vertex_area[v];
    map.sum[v] += a;
    map.count[v] += 1;
  }
  return den > 0 ? num / den : 0.0;
}

// The area-weighted mean of a_k(f) = ½(|wrap(θ_C(f) + θ_σC(σ(f)))| + |wrap(θ_σC(f) + θ_C(σ(f)))|).
double mirror_score_per_face(const FieldPair& t, const std::vector<int>& sigma, const std::vector<double>& area,
                             MapSums& map) {
  double num = 0, den = 0;
  for (std::size_t f = 0; f < area.size(); ++f) {
    const std::size_t g = static_cast<std::size_t>(sigma[f]);
    if (std::isnan(t.c[f]) || std::isnan(t.m[f]) || std::isnan(t.c[g]) || std::isnan(t.m[g])) continue;
    const double a = 0.5 * (std::abs(wrap_angle(t.c[f] + t.m[g])) + std::abs(wrap_angle(t.m[f] + t.c[g])));
    num += area[f] * a;
    den += area[f];
    map.sum[f] += a;
    map.count[f] += 1;
  }
  return den > 0 ? num / den : 0.0;
}

// Correspondence-free: circular W1 between the area-weighted distributions
// of θ_C and -θ_σ(C) (360 bins).
double correspondence_free_score(const FieldPair& t, const std::vector<double>& area) {
  const int B = 360;
  std::vector<double> h1(B, 0.0), h2(B, 0.0);
  double w1 = 0, w2 = 0;
  const auto bin = [&](double a) { return std::min(B - 1, static_cast<int>((a + kPi) / (2 * kPi) * B)); };
  for (std::size_t f = 0; f < area.size(); ++f) {
    if (!std::isnan(t.c[f])) h1[bin(t.c[f])] += area[f], w1 += area[f];
    if (!std::isnan(t.m[f])) h2[bin(wrap_angle(-t.m[f]))] += area[f], w2 += area[f];
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
  return w;
}

// SAF map, smoothed: the mean over configurations per vertex.
std::vector<double> saf_map_per_vertex(const MapSums& map) {
  std::vector<double> out(map.sum.size(), 0.0);
  for (std::size_t v = 0; v < out.size(); ++v)
    if (map.count[v] > 0) out[v] = map.sum[v] / map.count[v];
  return out;
}

// SAF map, per face: the mean over configurations per face, then the
// area-weighted mean of the incident faces.
std::vector<double> saf_map_from_faces(const Mesh& mesh, const MapSums& map, const std::vector<double>& area) {
  const std::size_t nv = mesh.vertices.size();
  std::vector<double> out(nv, 0.0), vw(nv, 0.0);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    if (map.count[f] == 0) continue;
    const double a = map.sum[f] / map.count[f];
    for (int k = 0; k < 3; ++k) {
      out[mesh.faces[f][k]] += area[f] * a;
      vw[mesh.faces[f][k]] += area[f];
    }
  }
  for (std::size_t v = 0; v < nv; ++v)
    if (vw[v] > 0) out[v] /= vw[v];
  return out;
}

// The SAF on a mesh already cut along the disks' circles (anchors on its
// surface, disk radius with the tolerance that takes in the cut's vertices).
SafResult saf_on(const Mesh& mesh, const LandmarkSet& anchors, const Plane& plane, const SafOptions& opt) {
  SafResult r;
  const LandmarkSet& lm = anchors;  // on the surface already (compute_saf projected them)
  r.disk_centres = lm;
  const SurfaceOperators ops = build_index_and_laplacian(mesh, opt.disk_radius_mm);
  const std::vector<FieldKey> fields = fields_of_configurations(opt.configurations, lm);
  const std::unique_ptr<SurfaceSmoother> smoother =
      prepare_factorisations(*ops.solver, mesh, fields, lm, opt.smoothing_mm);
  FieldGradients gradients(mesh, *ops.solver, lm);
  gradients.solve_prepared(distinct(fields));
  const auto area = geometry::face_areas(mesh);
  const std::vector<geometry::ClosestHit> vertex_mirror =
      smoother ? vertex_mirrors(mesh, *ops.index, plane) : std::vector<geometry::ClosestHit>{};
  const std::vector<int> sigma = smoother ? std::vector<int>{} : face_mirrors(mesh, *ops.index, plane);
  MapSums map(smoother ? mesh.vertices.size() : mesh.faces.size());
  double score_sum = 0, free_sum = 0;
  int used = 0;
  for (const auto& c : opt.configurations) {
    if (!complete(c, lm)) {
      r.skipped.push_back(c.name);
      continue;
    }
    const Configuration m = mirrored(c);
    FieldPair t;
    try {
      t.c = theta(mesh, gradients, c, opt.min_gradient_ratio);
      t.m = theta(mesh, gradients, m, opt.min_gradient_ratio);
    } catch (const std::exception&) {
      r.skipped.push_back(c.name);
      continue;
    }
    double s = 0;
    if (smoother) {
      const FieldPair st = smoothed_fields(*smoother, t, area);
      s = mirror_score_per_vertex(mesh, st, vertex_mirror, smoother->vertex_areas(), map);
      if (opt.keep_fields) {  // the fields the comparison uses: smoothed per vertex
        r.fields.push_back({c.name, false, c, st.c});
        r.fields.push_back({c.name, true, m, st.m});
      }
    } else {
      s = mirror_score_per_face(t, sigma, area, map);
      if (opt.keep_fields) {  // the fields the comparison uses: raw per face
        r.fields.push_back({c.name, false, c, t.c});
        r.fields.push_back({c.name, true, m, t.m});
      }
    }
    r.per_configuration[c.name] = s;
    score_sum += s;
    free_sum += correspondence_free_score(t, area);
    ++used;
  }
  r.factorisations = ops.solver->factorisations();
  if (used == 0) return r;
  r.score = score_sum / used;
  r.correspondence_free = free_sum / used;
  r.per_vertex = smoother ? saf_map_per_vertex(map) : saf_map_from_faces(mesh, map, area);
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
