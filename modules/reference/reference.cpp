#include "reference/reference.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Dense>

#include <cmath>
#include <memory>

#include "core/error.h"
#include "geometry/mesh_geometry.h"

namespace ms::reference {
namespace {

template <class T>
void reflect(const T* n, const T* d, const T* q, T* out) {
  const T s = n[0] * q[0] + n[1] * q[1] + n[2] * q[2] - d[0];
  for (int a = 0; a < 3; ++a) out[a] = q[a] - T(2) * s * n[a];
}

// Left landmark = q; right landmark = reflection of q.
struct PairResidual {
  Vec3 left, right;
  template <class T>
  bool operator()(const T* n, const T* d, const T* q, T* r) const {
    T rq[3];
    reflect(n, d, q, rq);
    for (int a = 0; a < 3; ++a) {
      r[a] = q[a] - T(left[a]);
      r[3 + a] = rq[a] - T(right[a]);
    }
    return true;
  }
};

// Midline landmark = projection of m onto the plane.
struct MidResidual {
  Vec3 p;
  template <class T>
  bool operator()(const T* n, const T* d, const T* m, T* r) const {
    const T s = n[0] * m[0] + n[1] * m[1] + n[2] * m[2] - d[0];
    for (int a = 0; a < 3; ++a) r[a] = m[a] - s * n[a] - T(p[a]);
    return true;
  }
};

// Reflected vertex to the tangent plane of its closest surface point.
struct MirrorResidual {
  Vec3 v, c, nc;
  template <class T>
  bool operator()(const T* n, const T* d, T* r) const {
    T q[3] = {T(v[0]), T(v[1]), T(v[2])}, rq[3];
    reflect(n, d, q, rq);
    r[0] = (rq[0] - T(c[0])) * T(nc[0]) + (rq[1] - T(c[1])) * T(nc[1]) + (rq[2] - T(c[2])) * T(nc[2]);
    return true;
  }
};

ceres::Solver::Options solver_options(int max_iterations) {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_QR;  // 4 to ~20 unknowns
  o.max_num_iterations = max_iterations;
  o.logging_type = ceres::SILENT;
  return o;
}

const char* kPairs[3] = {"Co", "Cr", "Go"};
const char* kMid[2] = {"Me", "Pog"};

// Moving vertex, after the rigid motion, to the tangent plane of its match.
struct RigidPointToPlane {
  Vec3 v, c, nc;
  template <class T>
  bool operator()(const T* aa, const T* t, T* r) const {
    const T p[3] = {T(v[0]), T(v[1]), T(v[2])};
    T q[3];
    ceres::AngleAxisRotatePoint(aa, p, q);
    r[0] = (q[0] + t[0] - T(c[0])) * T(nc[0]) + (q[1] + t[1] - T(c[1])) * T(nc[1]) + (q[2] + t[2] - T(c[2])) * T(nc[2]);
    return true;
  }
};

}  // namespace

Vec3 RigidTransform::apply(const Vec3& x) const {
  return {R[0] * x[0] + R[1] * x[1] + R[2] * x[2] + t[0], R[3] * x[0] + R[4] * x[1] + R[5] * x[2] + t[1],
          R[6] * x[0] + R[7] * x[1] + R[8] * x[2] + t[2]};
}

RigidTransform kabsch(const std::vector<std::pair<Vec3, Vec3>>& pairs) {
  RigidTransform T;
  if (pairs.empty()) return T;
  Eigen::Vector3d cm = Eigen::Vector3d::Zero(), cf = Eigen::Vector3d::Zero();
  for (const auto& [a, b] : pairs) cm += Eigen::Vector3d(a[0], a[1], a[2]), cf += Eigen::Vector3d(b[0], b[1], b[2]);
  cm /= static_cast<double>(pairs.size());
  cf /= static_cast<double>(pairs.size());
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (const auto& [a, b] : pairs) H += (Eigen::Vector3d(a[0], a[1], a[2]) - cm) * (Eigen::Vector3d(b[0], b[1], b[2]) - cf).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
  const Eigen::Matrix3d R = svd.matrixV() * D * svd.matrixU().transpose();
  const Eigen::Vector3d t = cf - R * cm;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) T.R[static_cast<std::size_t>(3 * r + c)] = R(r, c);
  T.t = {t[0], t[1], t[2]};
  return T;
}

RigidTransform RigidTransform::inverse() const {
  RigidTransform I;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) I.R[static_cast<std::size_t>(3 * r + c)] = R[static_cast<std::size_t>(3 * c + r)];
  I.t = -1.0 * I.apply(t);  // -R^T t (I.t is still zero here)
  return I;
}

AlignResult align_rigid(const Mesh& moving, const Mesh& fixed, const LandmarkSet& lm_moving, const LandmarkSet& lm_fixed,
                        int rounds, double cauchy_mm) {
  // Initial guess: Kabsch on common landmarks, else the centroids.
  std::vector<std::pair<Vec3, Vec3>> pairs;
  for (const auto& [name, p] : lm_moving.points)
    if (const Vec3* q = lm_fixed.find(name)) pairs.emplace_back(p, *q);
  RigidTransform initial;
  if (pairs.size() >= 3) {
    initial = kabsch(pairs);
  } else {
    Vec3 cm{0, 0, 0}, cf{0, 0, 0};
    for (const auto& v : moving.vertices) cm = cm + v;
    for (const auto& v : fixed.vertices) cf = cf + v;
    cm = (1.0 / static_cast<double>(std::max<std::size_t>(1, moving.vertices.size()))) * cm;
    cf = (1.0 / static_cast<double>(std::max<std::size_t>(1, fixed.vertices.size()))) * cf;
    initial.t = cf - cm;
  }
  AlignResult res = align_rigid_from(moving, fixed, initial, rounds, cauchy_mm);
  res.landmark_pairs = pairs.size() >= 3 ? pairs.size() : 0;
  return res;
}

AlignResult align_rigid_from(const Mesh& moving, const Mesh& fixed, const RigidTransform& initial, int rounds,
                             double cauchy_mm) {
  if (fixed.faces.empty() || moving.vertices.empty()) {
    AlignResult res;
    res.transform = initial;
    return res;
  }
  const geometry::ClosestPointIndex index(fixed);
  return align_rigid_from(moving, index, geometry::face_normals(fixed), initial, rounds, cauchy_mm);
}

AlignResult align_rigid_from(const Mesh& moving, const geometry::ClosestPointIndex& index,
                             const std::vector<Vec3>& fn, const RigidTransform& initial, int rounds, double cauchy_mm) {
  AlignResult res;
  Eigen::Matrix3d R0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R0(r, c) = initial.R[static_cast<std::size_t>(3 * r + c)];
  const Eigen::Vector3d t0(initial.t[0], initial.t[1], initial.t[2]);
  double aa[3], t[3] = {t0[0], t0[1], t0[2]};
  {
    const double Rm[9] = {R0(0, 0), R0(1, 0), R0(2, 0), R0(0, 1), R0(1, 1), R0(2, 1), R0(0, 2), R0(1, 2), R0(2, 2)};  // column-major
    ceres::RotationMatrixToAngleAxis(Rm, aa);
  }
  auto current = [&] {
    RigidTransform T;
    double Rc[9];
    ceres::AngleAxisToRotationMatrix(aa, Rc);  // column-major
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) T.R[3 * r + c] = Rc[3 * c + r];
    T.t = {t[0], t[1], t[2]};
    return T;
  };
  if (!fn.empty() && !moving.vertices.empty()) {
    const std::size_t step = std::max<std::size_t>(1, moving.vertices.size() / 6000);
    for (int round = 0; round < rounds; ++round) {
      const RigidTransform T = current();
      ceres::Problem pb;
      std::vector<double> dist;
      for (std::size_t i = 0; i < moving.vertices.size(); i += step) {
        const Vec3& v = moving.vertices[i];
        const auto hit = index.closest(T.apply(v));
        dist.push_back(hit.distance);
        pb.AddResidualBlock(new ceres::AutoDiffCostFunction<RigidPointToPlane, 1, 3, 3>(
                                new RigidPointToPlane{v, hit.point, fn[static_cast<std::size_t>(hit.face)]}),
                            new ceres::CauchyLoss(cauchy_mm), aa, t);
      }
      ceres::Solver::Summary s;
      ceres::Solve(solver_options(30), &pb, &s);
      std::nth_element(dist.begin(), dist.begin() + dist.size() / 2, dist.end());
      double ss = 0;
      for (std::size_t k = 0; k <= dist.size() / 2; ++k) ss += dist[k] * dist[k];
      res.rms_mm = std::sqrt(ss / static_cast<double>(dist.size() / 2 + 1));
      const RigidTransform N = current();
      double moved = 0;
      for (const Vec3& probe : {Vec3{0, 0, 0}, Vec3{50, 0, 0}, Vec3{0, 50, 0}, Vec3{0, 0, 50}})
        moved = std::max(moved, distance(N.apply(probe), T.apply(probe)));
      if (moved < 1e-3) break;
    }
  }
  res.transform = current();
  return res;
}

void plane_frame(const Plane& plane, Vec3& e_ml, Vec3& e_ap, Vec3& e_si, const Vec3& superior) {
  e_ml = normalized(plane.normal);
  Vec3 up = normalized(superior);
  if (std::abs(dot(up, e_ml)) > 0.9) up = {0, 1, 0};
  e_si = normalized(up - dot(up, e_ml) * e_ml);
  e_ap = cross(e_si, e_ml);
}

Plane refine_plane_on_surface(const Mesh& surface, const Plane& initial, const Options& opt, double* rms_mm,
                              const geometry::ClosestPointIndex* shared_index) {
  double n[3] = {initial.normal[0], initial.normal[1], initial.normal[2]};
  {
    const double l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (double& x : n) x /= l;
  }
  double d[1] = {n[0] * initial.point[0] + n[1] * initial.point[1] + n[2] * initial.point[2]};
  auto current_plane = [&] {
    Plane pl;
    pl.normal = normalized(Vec3{n[0], n[1], n[2]});
    pl.point = d[0] * pl.normal;
    return pl;
  };
  double rms = 0;
  if (surface.faces.size() > 100) {
    std::unique_ptr<geometry::ClosestPointIndex> own;
    if (!shared_index) own = std::make_unique<geometry::ClosestPointIndex>(surface);
    const geometry::ClosestPointIndex& index = shared_index ? *shared_index : *own;
    const auto fn = geometry::face_normals(surface);
    const std::size_t step = std::max<std::size_t>(1, surface.vertices.size() / opt.icp_samples);
    // Huber rounds converge from far; then redescending (Cauchy) rounds let
    // the asymmetric part of the surface stop pulling on the plane.
    const int total = opt.icp_rounds + (opt.icp_cauchy_mm > 0 ? opt.icp_rounds : 0);
    for (int round = 0; round < total; ++round) {
      const bool cauchy = round >= opt.icp_rounds;
      const Plane pl = current_plane();
      ceres::Problem icp;
      icp.AddParameterBlock(n, 3, new ceres::SphereManifold<3>());
      icp.AddParameterBlock(d, 1);
      // Closest points of the reflected samples, in parallel (the tree is
      // read-only); the residuals are then added in order.
      const long samples = static_cast<long>((surface.vertices.size() + step - 1) / step);
      std::vector<geometry::ClosestHit> hits(static_cast<std::size_t>(samples));
#pragma omp parallel for schedule(static)
      for (long s = 0; s < samples; ++s)
        hits[static_cast<std::size_t>(s)] = index.closest(pl.reflect(surface.vertices[static_cast<std::size_t>(s) * step]));
      for (std::size_t i = 0; i < surface.vertices.size(); i += step) {
        const Vec3& v = surface.vertices[i];
        const auto& hit = hits[i / step];
        ceres::LossFunction* loss = cauchy ? static_cast<ceres::LossFunction*>(new ceres::CauchyLoss(opt.icp_cauchy_mm))
                                           : static_cast<ceres::LossFunction*>(new ceres::HuberLoss(opt.icp_huber_mm));
        icp.AddResidualBlock(new ceres::AutoDiffCostFunction<MirrorResidual, 1, 3, 1>(
                                 new MirrorResidual{v, hit.point, fn[static_cast<std::size_t>(hit.face)]}),
                             loss, n, d);
      }
      ceres::Solver::Summary s;
      ceres::Solve(solver_options(30), &icp, &s);
      if (!cauchy) rms = std::sqrt(2.0 * s.final_cost / std::max(1, s.num_residual_blocks));  // Huber: ~squared
      const Plane np = current_plane();
      const double moved = std::acos(std::min(1.0, std::abs(dot(np.normal, pl.normal)))) * 180 / 3.14159265358979 +
                           std::abs(np.signed_distance(pl.point));
      if (moved < 1e-3) round = std::max(round, cauchy ? total : opt.icp_rounds - 1);  // converged: next stage
    }
  }
  if (rms_mm) *rms_mm = rms;
  return current_plane();
}

namespace {

// The plane's unknowns, as Ceres parameter blocks: the normal n (on
// SphereManifold<3>) and the offset d of the plane n·x = d.
struct PlaneUnknowns {
  double n[3] = {0, 0, 1};
  double d[1] = {0};
  Plane plane() const {
    Plane pl;
    pl.normal = normalized(Vec3{n[0], n[1], n[2]});
    pl.point = d[0] * pl.normal;
    return pl;
  }
};

// Initialisation: the normal along the mean left-right difference of the
// bilateral pairs, through the mean of the pairs' midpoints and the midline
// landmarks. *pairs: the number of bilateral pairs. Throws without one.
PlaneUnknowns initial_plane(const LandmarkSet& det, int* pairs) {
  Vec3 nsum{0, 0, 0};
  *pairs = 0;
  for (const char* p : kPairs) {
    const Vec3 *l = det.find(std::string(p) + "_L"), *r = det.find(std::string(p) + "_R");
    if (l && r) {
      nsum = nsum + (*l - *r);
      ++*pairs;
    }
  }
  if (*pairs == 0 || norm(nsum) < 1e-6)
    throw Error(ExitCode::GeometryFailed, "symmetry plane: no bilateral landmark pair was found");
  const Vec3 n0 = normalized(nsum);
  double acc = 0;
  int cnt = 0;
  for (const char* p : kPairs) {
    const Vec3 *l = det.find(std::string(p) + "_L"), *r = det.find(std::string(p) + "_R");
    if (l && r) acc += dot(n0, 0.5 * (*l + *r)), ++cnt;
  }
  for (const char* m : kMid)
    if (const Vec3* q = det.find(m)) acc += dot(n0, *q), ++cnt;
  PlaneUnknowns u;
  for (int a = 0; a < 3; ++a) u.n[a] = n0[a];
  u.d[0] = acc / cnt;
  return u;
}

// The symmetric configuration's unknowns: one free point q per bilateral
// pair (its partner is the reflection of q), one point per midline landmark
// (projected onto the plane); with the landmarks' names.
struct SymmetricConfiguration {
  std::vector<std::array<double, 3>> q_pair, q_mid;
  std::vector<std::string> pair_names, mid_names;
};

// Starting values: each pair's left point averaged with its reflected right
// point, each midline landmark as detected.
SymmetricConfiguration initial_configuration(const LandmarkSet& det, const PlaneUnknowns& u) {
  SymmetricConfiguration c;
  for (const char* p : kPairs) {
    const Vec3 *l = det.find(std::string(p) + "_L"), *r = det.find(std::string(p) + "_R");
    if (!l || !r) continue;
    Plane pl{Vec3{0, 0, 0}, Vec3{u.n[0], u.n[1], u.n[2]}};
    pl.point = u.d[0] * pl.normal;
    const Vec3 init = 0.5 * (*l + pl.reflect(*r));
    c.q_pair.push_back({init[0], init[1], init[2]});
    c.pair_names.push_back(p);
  }
  for (const char* m : kMid)
    if (const Vec3* q = det.find(m)) {
      c.q_mid.push_back({(*q)[0], (*q)[1], (*q)[2]});
      c.mid_names.push_back(m);
    }
  return c;
}

// Residuals detected - reference (Huber) between the detected landmarks and
// the symmetric configuration; the plane held fixed when plane_fixed.
void solve_configuration(PlaneUnknowns& u, SymmetricConfiguration& c, const LandmarkSet& det, double huber_mm,
                         bool plane_fixed) {
  ceres::Problem pb;
  pb.AddParameterBlock(u.n, 3, new ceres::SphereManifold<3>());
  pb.AddParameterBlock(u.d, 1);
  for (std::size_t i = 0; i < c.q_pair.size(); ++i) {
    const Vec3 *l = det.find(c.pair_names[i] + "_L"), *r = det.find(c.pair_names[i] + "_R");
    pb.AddResidualBlock(new ceres::AutoDiffCostFunction<PairResidual, 6, 3, 1, 3>(new PairResidual{*l, *r}),
                        new ceres::HuberLoss(huber_mm), u.n, u.d, c.q_pair[i].data());
  }
  for (std::size_t i = 0; i < c.q_mid.size(); ++i)
    pb.AddResidualBlock(new ceres::AutoDiffCostFunction<MidResidual, 3, 3, 1, 3>(new MidResidual{*det.find(c.mid_names[i])}),
                        new ceres::HuberLoss(huber_mm), u.n, u.d, c.q_mid[i].data());
  if (plane_fixed) {
    pb.SetParameterBlockConstant(u.n);
    pb.SetParameterBlockConstant(u.d);
  }
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options(100), &pb, &summary);
}

// The reported plane: normal to the patient's left, through the projection
// of the landmarks' centroid.
Plane reported_plane(const Plane& fitted, const LandmarkSet& det) {
  Plane out = fitted;
  if (out.normal[0] < 0) out.normal = -1.0 * out.normal;  // point to patient left
  Vec3 c{0, 0, 0};
  int cnt = 0;
  for (const auto& [name, p] : det.points) c = c + p, ++cnt;
  c = (1.0 / cnt) * c;
  out.point = c - fitted.signed_distance(c) * fitted.normal;
  return out;
}

// The reference configuration: each pair's q and its reflection, each
// midline point projected onto the plane.
LandmarkSet reference_configuration(const SymmetricConfiguration& c, const Plane& pl) {
  LandmarkSet out;
  for (std::size_t i = 0; i < c.q_pair.size(); ++i) {
    const Vec3 q{c.q_pair[i][0], c.q_pair[i][1], c.q_pair[i][2]};
    out.set(c.pair_names[i] + "_L", q);
    out.set(c.pair_names[i] + "_R", pl.reflect(q));
  }
  for (std::size_t i = 0; i < c.q_mid.size(); ++i) {
    const Vec3 m{c.q_mid[i][0], c.q_mid[i][1], c.q_mid[i][2]};
    out.set(c.mid_names[i], m - pl.signed_distance(m) * pl.normal);
  }
  return out;
}

// Asymmetry vectors (detected - reference) in the plane frame, and their RMS.
void asymmetry_vectors(Result& res, const LandmarkSet& det, const Vec3& superior) {
  Vec3 e_ml, e_ap, e_si;
  plane_frame(res.plane, e_ml, e_ap, e_si, superior);
  double ss = 0;
  int cnt = 0;
  for (const auto& [name, ref] : res.reference.points) {
    const Vec3 dv = *det.find(name) - ref;
    ss += dot(dv, dv);
    ++cnt;
    res.asymmetry_vectors[name] = {dot(dv, e_ml), dot(dv, e_ap), dot(dv, e_si)};
  }
  res.rms_landmark_residual_mm = cnt ? std::sqrt(ss / cnt) : 0.0;
}

}  // namespace

Result fit(const LandmarkSet& det, const Mesh* surface, const Options& opt) {
  int pairs = 0;
  PlaneUnknowns u = initial_plane(det, &pairs);
  // Stage 1: landmarks vs the symmetric configuration.
  SymmetricConfiguration config = initial_configuration(det, u);
  solve_configuration(u, config, det, opt.landmark_huber_mm, false);
  Result res;
  // Stage 2: mirror-ICP on the surface, then the configuration re-solved
  // for the refined plane (plane fixed).
  if (opt.refine_on_surface && surface && surface->faces.size() > 100) {
    double rms = 0;
    const Plane refined = refine_plane_on_surface(*surface, u.plane(), opt, &rms);
    for (int a = 0; a < 3; ++a) u.n[a] = refined.normal[a];
    u.d[0] = dot(refined.normal, refined.point);
    res.surface_rms_mm = rms;
    solve_configuration(u, config, det, opt.landmark_huber_mm, true);
  }
  const Plane pl = u.plane();
  res.plane = reported_plane(pl, det);
  res.reference = reference_configuration(config, pl);
  asymmetry_vectors(res, det, opt.superior);
  if (pairs < 2) res.warnings.push_back("symmetry plane from a single bilateral landmark pair");
  return res;
}

CranialResult cranial_plane(const Mesh& cranium, double volume_cm3, const Plane& mandible_plane, const LandmarkSet& landmarks,
                            const Options& options) {
  CranialResult r;
  r.bone_volume_cm3 = volume_cm3;
  if (volume_cm3 < 50 || cranium.faces.empty()) {
    r.reason = "the scan holds too little skull above the condyles (" + std::to_string(static_cast<int>(volume_cm3)) + " cm3)";
    return r;
  }
  std::size_t left = 0;
  for (const auto& v : cranium.vertices) left += mandible_plane.signed_distance(v) > 0;
  const double frac = static_cast<double>(left) / static_cast<double>(cranium.vertices.size());
  if (frac < 0.25 || frac > 0.75) {
    r.reason = "the scan holds too little of one side of the skull";
    return r;
  }
  double rms = -1;
  r.plane = refine_plane_on_surface(cranium, mandible_plane, options, &rms);
  if (dot(r.plane.normal, mandible_plane.normal) < 0) r.plane.normal = -1.0 * r.plane.normal;
  r.found = true;
  r.surface_rms_mm = rms;
  r.angle_to_mandible_plane_deg =
      std::acos(std::clamp(std::abs(dot(normalized(r.plane.normal), normalized(mandible_plane.normal))), 0.0, 1.0)) * 180 / M_PI;
  auto add = [&](const std::string& name, const Vec3& p) {
    r.to_cranial_mm[name] = r.plane.signed_distance(p);
    r.to_mandible_mm[name] = mandible_plane.signed_distance(p);
  };
  for (const char* n : {"Me", "Pog"})
    if (const Vec3* p = landmarks.find(n)) add(n, *p);
  const Vec3 *cl = landmarks.find("Co_L"), *cr = landmarks.find("Co_R");
  if (cl && cr) add("condylar_midpoint", 0.5 * (*cl + *cr));
  return r;
}

}  // namespace ms::reference
