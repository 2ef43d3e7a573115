#include "descriptors/matching.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>

#include "descriptors/spin_image.h"
#include "geometry/mesh_geometry.h"

namespace ms::descriptors {

std::vector<Neighbour> nearest(const std::vector<float>& query, const std::vector<float>& base, int len, int k) {
  // |a - b|^2 = |a|^2 + |b|^2 - 2 a.b, the products by blocks of one matrix
  // product (Eigen GEMM) instead of a scalar loop per pair.
  using Rows = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const Eigen::Index L = len, nq = static_cast<Eigen::Index>(query.size()) / L, nb = static_cast<Eigen::Index>(base.size()) / L;
  const std::size_t K = static_cast<std::size_t>(k);
  std::vector<Neighbour> out(static_cast<std::size_t>(nq) * K, Neighbour{-1, std::numeric_limits<float>::infinity()});
  if (nq == 0 || nb == 0) return out;
  const Eigen::Map<const Rows> Q(query.data(), nq, L), B(base.data(), nb, L);
  const Eigen::VectorXf qn = Q.rowwise().squaredNorm(), bn = B.rowwise().squaredNorm();
  const Eigen::Index block = 256;
  for (Eigen::Index q0 = 0; q0 < nq; q0 += block) {
    const Eigen::Index m = std::min(block, nq - q0);
    const Rows G = Q.middleRows(q0, m) * B.transpose();
#pragma omp parallel for schedule(static)
    for (Eigen::Index i = 0; i < m; ++i) {
      Neighbour* best = out.data() + static_cast<std::size_t>(q0 + i) * K;  // ascending by squared distance
      for (Eigen::Index j = 0; j < nb; ++j) {
        const float d2 = std::max(0.0f, qn[q0 + i] + bn[j] - 2 * G(i, j));
        if (!(d2 < best[K - 1].distance)) continue;
        std::size_t pos = K - 1;
        while (pos > 0 && d2 < best[pos - 1].distance) best[pos] = best[pos - 1], --pos;
        best[pos] = {static_cast<int>(j), d2};
      }
      for (std::size_t j = 0; j < K; ++j) best[j].distance = std::sqrt(best[j].distance);
    }
  }
  return out;
}

namespace {

double refit_rms(const reference::RigidTransform& T, const std::vector<Vec3>& src, const std::vector<Vec3>& dst,
                 const std::vector<int>& idx) {
  double ss = 0;
  for (int i : idx) {
    const Vec3 e = T.apply(src[static_cast<std::size_t>(i)]) - dst[static_cast<std::size_t>(i)];
    ss += dot(e, e);
  }
  return idx.empty() ? 0.0 : std::sqrt(ss / static_cast<double>(idx.size()));
}

}  // namespace

RansacResult ransac_rigid(const std::vector<Vec3>& src, const std::vector<Vec3>& dst, double inlier_mm, int iterations,
                          std::uint64_t seed) {
  RansacResult best;
  const std::size_t n = std::min(src.size(), dst.size());
  if (n < 3) return best;
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, n - 1);
  const double t2 = inlier_mm * inlier_mm;
  std::vector<int> inl;
  auto count = [&](const reference::RigidTransform& T) {
    inl.clear();
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3 e = T.apply(src[i]) - dst[i];
      if (dot(e, e) <= t2) inl.push_back(static_cast<int>(i));
    }
  };
  for (int it = 0; it < iterations; ++it) {
    const std::size_t a = pick(rng), b = pick(rng), c = pick(rng);
    if (a == b || b == c || a == c) continue;
    // A minimal sample must be non-degenerate and distance-consistent (rigid).
    const double ds[3] = {distance(src[a], src[b]), distance(src[b], src[c]), distance(src[a], src[c])};
    const double dd[3] = {distance(dst[a], dst[b]), distance(dst[b], dst[c]), distance(dst[a], dst[c])};
    bool ok = norm(cross(src[b] - src[a], src[c] - src[a])) > 4 * t2;
    for (int k = 0; k < 3 && ok; ++k) ok = std::abs(ds[k] - dd[k]) <= 2 * inlier_mm;
    if (!ok) continue;
    const auto T = reference::kabsch({{src[a], dst[a]}, {src[b], dst[b]}, {src[c], dst[c]}});
    count(T);
    if (inl.size() > best.inliers.size()) best.transform = T, best.inliers = inl;
  }
  // Refit on the inliers (twice: the refit may gather a few more).
  for (int round = 0; round < 2 && best.inliers.size() >= 3; ++round) {
    std::vector<std::pair<Vec3, Vec3>> pairs;
    for (int i : best.inliers) pairs.emplace_back(src[static_cast<std::size_t>(i)], dst[static_cast<std::size_t>(i)]);
    const auto T = reference::kabsch(pairs);
    count(T);
    if (inl.size() < best.inliers.size()) break;
    best.transform = T, best.inliers = inl;
  }
  best.rms_mm = refit_rms(best.transform, src, dst, best.inliers);
  return best;
}

namespace {

// The faces of mesh whose three vertices are within radius of c, reindexed;
// original (optional) receives the source index of every patch vertex.
Mesh patch(const Mesh& mesh, const Vec3& c, double radius, std::vector<int>* original = nullptr) {
  Mesh out;
  std::vector<int> map(mesh.vertices.size(), -1);
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v)
    if (distance(mesh.vertices[v], c) <= radius) {
      map[v] = static_cast<int>(out.vertices.size());
      out.vertices.push_back(mesh.vertices[v]);
      if (original) original->push_back(static_cast<int>(v));
    }
  for (const auto& f : mesh.faces) {
    const int a = map[static_cast<std::size_t>(f[0])], b = map[static_cast<std::size_t>(f[1])], d = map[static_cast<std::size_t>(f[2])];
    if (a >= 0 && b >= 0 && d >= 0) out.faces.push_back({a, b, d});
  }
  return out;
}

std::string fmt(double v) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(1);
  s << v;
  return s.str();
}

}  // namespace

std::vector<LandmarkTransfer> transfer_landmarks(const Mesh& source, const LandmarkSet& source_landmarks, const Mesh& target,
                                                 const LandmarkSet& target_landmarks,
                                                 const reference::RigidTransform& global, const TransferOptions& opt) {
  std::vector<LandmarkTransfer> out;
  if (source.faces.empty() || target.faces.empty()) return out;
  // One descriptor set per mesh, same absolute parameters on both (the support
  // radius follows the coarser of the two resolutions).
  const double res = std::max(mesh_resolution(source), mesh_resolution(target));
  Options dopt;
  dopt.support_radius_mm = 10 * res;
  const SpinImages src_isi(source, dopt), tgt_isi(target, dopt);
  const double inlier_mm = opt.inlier_mm > 0 ? opt.inlier_mm : 3 * res;
  const geometry::ClosestPointIndex target_index(target);
  const auto target_normals = geometry::face_normals(target);
  const int len = src_isi.length();
  std::mt19937_64 rng(opt.seed);
  // Target keypoints: one random sample of the whole surface, described once
  // and shared by all landmarks.
  std::vector<int> tgt_sample(target.vertices.size());
  std::iota(tgt_sample.begin(), tgt_sample.end(), 0);
  std::shuffle(tgt_sample.begin(), tgt_sample.end(), rng);
  if (tgt_sample.size() > static_cast<std::size_t>(opt.target_features)) tgt_sample.resize(static_cast<std::size_t>(opt.target_features));
  const auto tgt_desc = tgt_isi.compute(Kind::kImprovedSpinImage, tgt_sample);

  for (const auto& [name, L] : source_landmarks.points) {
    LandmarkTransfer t;
    t.name = name;
    if (const Vec3* d = target_landmarks.find(name)) t.detected = true, t.detected_point = *d;
    // The patch around the landmark (registered by ICP below); its keypoints
    // are a random sample of its vertices.
    std::vector<int> src_pts;
    const Mesh p = patch(source, L, opt.patch_radius_mm, &src_pts);
    std::shuffle(src_pts.begin(), src_pts.end(), rng);
    if (src_pts.size() > static_cast<std::size_t>(opt.patch_features)) src_pts.resize(static_cast<std::size_t>(opt.patch_features));
    // Target candidates: the sampled vertices near where the global
    // alignment puts the landmark.
    const Vec3 guess = global.apply(L);
    const double reach = opt.search_radius_mm + opt.patch_radius_mm;
    std::vector<int> tgt_pts;  // indices into tgt_sample
    std::vector<float> dt;
    for (std::size_t k = 0; k < tgt_sample.size(); ++k)
      if (distance(target.vertices[static_cast<std::size_t>(tgt_sample[k])], guess) <= reach) {
        tgt_pts.push_back(tgt_sample[k]);
        dt.insert(dt.end(), tgt_desc.begin() + static_cast<std::ptrdiff_t>(k * static_cast<std::size_t>(len)),
                  tgt_desc.begin() + static_cast<std::ptrdiff_t>((k + 1) * static_cast<std::size_t>(len)));
      }
    if (src_pts.size() < 3 || tgt_pts.size() < 3) {
      t.reason = "too little surface around the landmark to register";
      out.push_back(t);
      continue;
    }
    const auto ds = src_isi.compute(Kind::kImprovedSpinImage, src_pts);
    const auto nn = nearest(ds, dt, len, 2);
    std::vector<Vec3> a, b;
    for (std::size_t q = 0; q < src_pts.size(); ++q)
      for (int j = 0; j < 2; ++j) {
        const auto& m = nn[q * 2 + static_cast<std::size_t>(j)];
        if (m.index < 0) continue;
        a.push_back(source.vertices[static_cast<std::size_t>(src_pts[q])]);
        b.push_back(target.vertices[static_cast<std::size_t>(tgt_pts[static_cast<std::size_t>(m.index)])]);
      }
    const auto rs = ransac_rigid(a, b, inlier_mm, opt.ransac_iterations, opt.seed + out.size());
    t.inliers = static_cast<int>(rs.inliers.size());
    if (rs.inliers.size() < 6) {
      t.reason = "no consistent descriptor matches (" + std::to_string(rs.inliers.size()) + " inliers)";
      out.push_back(t);
      continue;
    }
    // Refine the patch on the target surface.
    const auto icp = reference::align_rigid_from(p, target_index, target_normals, rs.transform, 20, 0.5);
    std::size_t close = 0;
    for (const auto& v : p.vertices)
      if (target_index.closest(icp.transform.apply(v)).distance <= 1.0) ++close;
    t.overlap = p.vertices.empty() ? 0.0 : static_cast<double>(close) / static_cast<double>(p.vertices.size());
    t.rms_mm = icp.rms_mm;
    t.transferred = target_index.closest(icp.transform.apply(L)).point;
    t.registered = t.overlap >= opt.min_overlap;
    if (t.detected) t.disagreement_mm = distance(t.detected_point, t.transferred);
    if (!t.registered) {
      t.reason = "neighbourhood changed: only " + fmt(100 * t.overlap) + " % of it fits the other scan";
    } else if (!t.detected) {
      t.used = true;
      t.reason = "not detected on this scan";
    } else if (t.disagreement_mm > opt.agree_mm) {
      t.used = true;
      t.reason = "detection " + fmt(t.disagreement_mm) + " mm from the registered neighbourhood";
    } else {
      t.reason = "detection agrees (" + fmt(t.disagreement_mm) + " mm)";
    }
    out.push_back(t);
  }
  return out;
}

}  // namespace ms::descriptors
