// Spin Image / Improved Spin Image properties (docs/descriptors.md) and
// landmark transfer between two scans of one mandible.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "descriptors/matching.h"
#include "descriptors/spin_image.h"
#include "geometry/mesh_geometry.h"
#include "phantom/phantom.h"
#include "surface/surface.h"

using ms::Mesh;
using ms::Vec3;
using ms::operator+;
using ms::operator-;
using ms::operator*;
namespace d = ms::descriptors;

namespace {

// Ground-truth phantom mandible surface (neutral pose, no noise), meshed with
// the given edge length. Shared: building it costs a few seconds.
struct Fixture {
  Mesh mesh;
  ms::LandmarkSet landmarks;
};
const Fixture& mandible(double edge_mm = 1.0) {
  static std::map<double, Fixture> cache;
  auto it = cache.find(edge_mm);
  if (it != cache.end()) return it->second;
  ms::phantom::PhantomParams p;
  p.spacing = {1, 1, 1};
  p.fov_mm = {150, 140, 130};
  p.noise_hu = 0;
  p.occlusal_gap_mm = 2;
  const auto ph = ms::phantom::generate(p);
  ms::surface::Options so;
  so.target_edge_mm = edge_mm;
  Fixture f{ms::surface::mesh_from_mask(ph.mandible, so).mesh, {}};
  const ms::geometry::ClosestPointIndex idx(f.mesh);
  for (const auto& [name, q] : ph.landmarks.points) f.landmarks.set(name, idx.closest(q).point);
  return cache.emplace(edge_mm, std::move(f)).first->second;
}

ms::reference::RigidTransform rotation(double ax, double ay, double az, const Vec3& t) {
  const double a = ax * M_PI / 180, b = ay * M_PI / 180, c = az * M_PI / 180;
  // Rz(c) Ry(b) Rx(a)
  const double ca = std::cos(a), sa = std::sin(a), cb = std::cos(b), sb = std::sin(b), cc = std::cos(c), sc = std::sin(c);
  ms::reference::RigidTransform T;
  T.R = {cc * cb, cc * sb * sa - sc * ca, cc * sb * ca + sc * sa,
         sc * cb, sc * sb * sa + cc * ca, sc * sb * ca - cc * sa,
         -sb,     cb * sa,                cb * ca};
  T.t = t;
  return T;
}

Mesh moved(const Mesh& m, const ms::reference::RigidTransform& T) {
  Mesh out = m;
  for (auto& v : out.vertices) v = T.apply(v);
  return out;
}

std::vector<int> sample(std::size_t n, std::size_t count, std::uint64_t seed) {
  std::vector<int> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<int>(i);
  std::mt19937_64 rng(seed);
  std::shuffle(v.begin(), v.end(), rng);
  v.resize(std::min(n, count));
  return v;
}

float row_distance(const std::vector<float>& a, std::size_t i, const std::vector<float>& b, std::size_t j, int len) {
  float s = 0;
  for (int k = 0; k < len; ++k) {
    const float e = a[i * static_cast<std::size_t>(len) + static_cast<std::size_t>(k)] - b[j * static_cast<std::size_t>(len) + static_cast<std::size_t>(k)];
    s += e * e;
  }
  return std::sqrt(s);
}

// Height field z = c (x^2 + y^2) on a grid, triangles oriented so that normals
// point to +z (the side a bowl's inside faces when c > 0; a dome's outside when c < 0).
Mesh height_field(double c, double half = 10, int n = 41) {
  Mesh m;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double x = -half + 2 * half * i / (n - 1), y = -half + 2 * half * j / (n - 1);
      m.vertices.push_back({x, y, c * (x * x + y * y)});
    }
  for (int j = 0; j + 1 < n; ++j)
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i, b = a + 1, e = a + n, f = e + 1;
      m.faces.push_back({a, b, f});
      m.faces.push_back({a, f, e});
    }
  return m;
}

}  // namespace

TEST(SpinImage, SignedAngleIsPositiveTowardsTheNormalRayAndFlipsAway) {
  const Vec3 p{0, 0, 0}, n{0, 0, 1}, x{5, 0, 0};
  const double t = 0.3;
  const Vec3 towards{-std::sin(t), 0, std::cos(t)}, away{std::sin(t), 0, std::cos(t)};
  EXPECT_NEAR(d::signed_normal_angle(p, n, x, towards), t, 1e-12);
  EXPECT_NEAR(d::signed_normal_angle(p, n, x, away), -t, 1e-12);
  // Independent of where around the ray the neighbour sits.
  const Vec3 x2{0, -5, 3};
  EXPECT_NEAR(d::signed_normal_angle(p, n, x2, Vec3{0, std::sin(t), std::cos(t)}), t, 1e-12);
}

TEST(SpinImage, ConcaveAndConvexNeighbourhoodsFillOppositeHalvesOfTheIsi) {
  // Bowl (concave towards its normals) vs dome (convex): same |curvature|.
  for (const double c : {0.02, -0.02}) {
    const Mesh m = height_field(c);
    d::Options o;
    o.support_radius_mm = 8;
    o.bins = 10;
    const d::SpinImages si(m, o);
    const int centre = 20 * 41 + 20;
    const auto img = si.image(d::Kind::kImprovedSpinImage, centre);
    double pos = 0, neg = 0;
    for (int r = 0; r < o.bins; ++r)
      for (int col = 0; col < o.bins; ++col) (col < o.bins / 2 ? neg : pos) += img[static_cast<std::size_t>(r * o.bins + col)];
    if (c > 0) EXPECT_GT(pos, 5 * neg) << "bowl: neighbours lean towards the normal ray";
    else EXPECT_GT(neg, 5 * pos) << "dome: neighbours lean away";
    // The classic SI sees the height: bowl above the tangent plane, dome below.
    const auto s = si.image(d::Kind::kSpinImage, centre);
    double up = 0, down = 0;
    for (int r = 0; r < o.bins; ++r)
      for (int col = 0; col < o.bins; ++col) (col < o.bins / 2 ? down : up) += s[static_cast<std::size_t>(r * o.bins + col)];
    if (c > 0) EXPECT_GT(up, down);
    else EXPECT_GT(down, up);
  }
}

TEST(SpinImage, FrameIsOrthonormalRightHandedAndOutward) {
  const auto& f = mandible();
  const d::SpinImages si(f.mesh);
  const auto vn = ms::geometry::vertex_normals(f.mesh);
  for (int v : sample(f.mesh.vertices.size(), 200, 3)) {
    const auto fr = si.frame(v, si.support_radius());
    EXPECT_NEAR(ms::norm(fr.x), 1, 1e-9);
    EXPECT_NEAR(ms::dot(fr.x, fr.z), 0, 1e-9);
    EXPECT_NEAR(ms::distance(ms::cross(fr.z, fr.x), fr.y), 0, 1e-9);
    EXPECT_GE(ms::dot(fr.z, vn[static_cast<std::size_t>(v)]), 0);
  }
}

TEST(SpinImage, DescriptorsAreInvariantToRigidMotion) {
  const auto& f = mandible();
  const auto T = rotation(35, -50, 120, {40, -17, 230});
  const d::SpinImages a(f.mesh), b(moved(f.mesh, T));
  const auto idx = sample(f.mesh.vertices.size(), 300, 7);
  for (const auto kind : {d::Kind::kSpinImage, d::Kind::kImprovedSpinImage}) {
    const auto da = a.compute(kind, idx), db = b.compute(kind, idx);
    double worst = 0;
    for (std::size_t k = 0; k < idx.size(); ++k) worst = std::max<double>(worst, row_distance(da, k, db, k, a.length()));
    EXPECT_LT(worst, 1e-4) << (kind == d::Kind::kSpinImage ? "SI" : "ISI");
    // And not trivially: descriptors differ from place to place.
    EXPECT_GT(row_distance(da, 0, da, 1, a.length()) + row_distance(da, 2, da, 3, a.length()), 0.05);
  }
  // The frame moves with the mesh.
  const auto fa = a.frame(idx[0], a.support_radius()), fb = b.frame(idx[0], b.support_radius());
  const Vec3 rz = T.apply(fa.z) - T.t, rx = T.apply(fa.x) - T.t;
  EXPECT_NEAR(ms::distance(rz, fb.z), 0, 1e-6);
  EXPECT_NEAR(ms::distance(rx, fb.x), 0, 1e-6);
}

TEST(SpinImage, StableUnderRemeshing) {
  // The same bone meshed at 1.0 and 0.7 mm edges: the descriptor at a point
  // stays much closer to the descriptor at the same place than to those of
  // other places, and the nearest descriptor lands near the same place.
  const auto& coarse = mandible(1.0);
  const auto& fine = mandible(0.7);
  d::Options o;
  o.support_radius_mm = 10;  // same absolute support on both meshes
  const d::SpinImages a(coarse.mesh, o), b(fine.mesh, o);
  const auto ia = sample(coarse.mesh.vertices.size(), 400, 11);
  std::vector<int> ib;
  for (int v : ia) ib.push_back(ms::geometry::nearest_vertex(fine.mesh, coarse.mesh.vertices[static_cast<std::size_t>(v)]));
  const auto others = sample(fine.mesh.vertices.size(), 4000, 12);
  for (const auto kind : {d::Kind::kSpinImage, d::Kind::kImprovedSpinImage}) {
    const auto da = a.compute(kind, ia), db = b.compute(kind, ib), dother = b.compute(kind, others);
    std::vector<double> same, diff;
    for (std::size_t k = 0; k < ia.size(); ++k) {
      same.push_back(row_distance(da, k, db, k, a.length()));
      diff.push_back(row_distance(da, k, dother, k, a.length()));
    }
    std::nth_element(same.begin(), same.begin() + same.size() / 2, same.end());
    std::nth_element(diff.begin(), diff.begin() + diff.size() / 2, diff.end());
    const double ms = same[same.size() / 2], md = diff[diff.size() / 2];
    EXPECT_LT(ms, 0.33 * md) << (kind == d::Kind::kSpinImage ? "SI" : "ISI") << " same " << ms << " other " << md;
    // Nearest neighbour among the fine mesh's sample + the true points.
    auto base = dother;
    base.insert(base.end(), db.begin(), db.end());
    const auto nn = d::nearest(da, base, a.length(), 1);
    int near = 0;
    for (std::size_t k = 0; k < ia.size(); ++k) {
      const std::size_t j = static_cast<std::size_t>(nn[k].index);
      const int v = j < others.size() ? others[j] : ib[j - others.size()];
      near += ms::distance(fine.mesh.vertices[static_cast<std::size_t>(v)], coarse.mesh.vertices[static_cast<std::size_t>(ia[k])]) <= 3.0;
    }
    std::printf("%s remeshing: median distance same place %.3f, other places %.3f, nearest within 3 mm %d/%zu\n",
                kind == d::Kind::kSpinImage ? "SI " : "ISI", ms, md, near, ia.size());
    EXPECT_GT(near, static_cast<int>(ia.size()) / 2);
  }
}

TEST(Ransac, RecoversATransformFromHalfOutliers) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-30, 30);
  const auto T = rotation(10, 20, -40, {5, 6, -7});
  std::vector<Vec3> a, b;
  for (int i = 0; i < 100; ++i) {
    const Vec3 p{u(rng), u(rng), u(rng)};
    a.push_back(p);
    b.push_back(i % 2 ? Vec3{u(rng), u(rng), u(rng)} : T.apply(p));
  }
  const auto r = d::ransac_rigid(a, b, 0.5, 500, 1);
  EXPECT_EQ(r.inliers.size(), 50u);
  for (const Vec3& p : {Vec3{0, 0, 0}, Vec3{40, -20, 10}}) EXPECT_NEAR(ms::distance(r.transform.apply(p), T.apply(p)), 0, 1e-9);
  EXPECT_TRUE(d::ransac_rigid({a[0], a[1]}, {b[0], b[1]}, 0.5, 10, 1).inliers.empty());
}

TEST(LandmarkTransfer, CorrectsAMisplacedAndAMissingDetectionAfterASegmentMoved) {
  // Post-operative scan: the tooth-bearing segment advanced 5 mm and rotated
  // 5 degrees (a bilateral split osteotomy: the cut 16 mm in front of the
  // coronoid tips, blended over 4 mm), the bone repositioned in the scanner,
  // and the detector thrown off at Go_L by 7 mm (a plate) and missing Me. The
  // two scans are meshed independently (1.0 vs 0.7 mm edges) and the post
  // surface carries 0.1 mm noise.
  const auto& f = mandible(1.0);
  const auto& g = mandible(0.7);
  const double cut = 0.5 * ((*f.landmarks.find("Cr_L"))[1] + (*f.landmarks.find("Cr_R"))[1]) - 16;  // LPS y
  const auto tilt = rotation(5, 0, 0, {0, 0, 0});
  const Vec3 hinge{0, cut, 0};
  auto advanced = [&](const Vec3& p) {
    const double w = std::clamp((cut - p[1]) / 4, 0.0, 1.0);  // 1 in front of the cut (smaller y = anterior)
    return (1 - w) * p + w * (tilt.apply(p - hinge) + hinge + Vec3{0, -5, 0});
  };
  const auto T = rotation(8, -5, 12, {3, -9, 20});
  Mesh post = g.mesh;
  std::mt19937_64 rng(9);
  std::normal_distribution<double> noise(0, 0.1);
  for (auto& v : post.vertices) v = T.apply(advanced(v)) + Vec3{noise(rng), noise(rng), noise(rng)};
  ms::LandmarkSet truth_post, detected;
  for (const auto& [name, p] : g.landmarks.points) truth_post.set(name, T.apply(advanced(p)));
  for (const auto& [name, p] : truth_post.points)
    if (name != "Me") detected.set(name, name == "Go_L" ? p + Vec3{0, 0, -7} : p);
  const auto tr = d::transfer_landmarks(f.mesh, f.landmarks, post, detected, T);
  ASSERT_EQ(tr.size(), f.landmarks.points.size());
  for (const auto& t : tr) {
    const double err = ms::distance(t.transferred, *truth_post.find(t.name));
    std::printf("%-5s registered %d used %d overlap %.2f inliers %d rms %.2f error %.2f mm  %s\n", t.name.c_str(),
                t.registered, t.used, t.overlap, t.inliers, t.rms_mm, err, t.reason.c_str());
    EXPECT_TRUE(t.registered) << t.name;
    EXPECT_LT(err, 1.0) << t.name;
    EXPECT_EQ(t.used, t.name == "Go_L" || t.name == "Me") << t.name;
  }
}

TEST(LandmarkTransfer, KeepsAConsistentDetectionWhereSurgeryReshapedTheBone) {
  // The chin reshaped (genioplasty-like: the region around Pog pushed out
  // 4 mm, smoothly) and Pog detected where the new chin is: nothing to
  // transfer there; the condyles, far away, register and agree.
  const auto& f = mandible();
  const Vec3 pog = *f.landmarks.find("Pog");
  Mesh post = f.mesh;
  const auto vn = ms::geometry::vertex_normals(f.mesh);
  for (std::size_t v = 0; v < post.vertices.size(); ++v) {
    const double r = ms::distance(post.vertices[v], pog);
    post.vertices[v] = post.vertices[v] + 4 * std::exp(-r * r / (2 * 8.0 * 8.0)) * vn[v];
  }
  ms::LandmarkSet detected = f.landmarks;
  detected.set("Pog", pog + Vec3{0, -4, 0});
  const auto tr = d::transfer_landmarks(f.mesh, f.landmarks, post, detected, ms::reference::RigidTransform{});
  for (const auto& t : tr) {
    std::printf("%-5s registered %d used %d overlap %.2f %s\n", t.name.c_str(), t.registered, t.used, t.overlap, t.reason.c_str());
    if (t.name == "Pog") {  // kept because it agrees with the registered chin, not because registration failed
      EXPECT_TRUE(t.registered);
      EXPECT_LT(t.disagreement_mm, 3.0);
      EXPECT_FALSE(t.used);
    }
    if (t.name == "Co_L" || t.name == "Co_R") {
      EXPECT_TRUE(t.registered);
      EXPECT_FALSE(t.used);
    }
  }
}
