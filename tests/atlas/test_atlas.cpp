// The mandible atlas (docs/atlas.md): pose algebra, serialisation, the search
// recovering a known pose and a known flip, and the fit on a real scan.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "atlas/atlas.h"
#include "core/error.h"
#include "tests/support/openkbp.h"

using namespace ms;
using namespace ms::atlas;

namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

// A scan-like field: the shipped atlas's context placed by `pose` on a 3 mm
// grid around it (0 where the atlas box does not reach).
Field posed_context(const Pose& pose) {
  const Atlas& a = shipped();
  Field ctx;
  ctx.grid = a.grid;
  ctx.v = a.context;
  Field f;
  f.grid.spacing = 3.0;
  for (int k = 0; k < 3; ++k) {
    f.grid.n[k] = 140;
    f.grid.origin[k] = pose.t[k] - 210.0;
  }
  f.v.assign(f.grid.count(), 0.0f);
  for (int k = 0; k < f.grid.n[2]; ++k)
    for (int j = 0; j < f.grid.n[1]; ++j)
      for (int i = 0; i < f.grid.n[0]; ++i) {
        const Vec3 p{f.grid.origin[0] + 3.0 * i, f.grid.origin[1] + 3.0 * j, f.grid.origin[2] + 3.0 * k};
        const float v = ctx.at(pose.inverse(p));
        f.v[f.grid.linear(i, j, k)] = std::isnan(v) ? 0.0f : v;
      }
  return f;
}

}  // namespace

TEST(Atlas, PoseInverseUndoesApply) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int n = 0; n < 50; ++n) {
    Pose p;
    p.t = {50 * u(rng), 50 * u(rng), 50 * u(rng)};
    p.pitch = 0.5 * u(rng), p.yaw = 0.5 * u(rng), p.roll = 0.5 * u(rng);
    p.scale = 1.0 + 0.3 * u(rng);
    p.flip = n % 4;
    const Vec3 a{80 * u(rng), 80 * u(rng), 80 * u(rng)};
    EXPECT_LT(distance(p.inverse(p.apply(a)), a), 1e-9);
    // A flip is a mirror: it changes the handedness (determinant sign) of the map.
    const Vec3 o = p.apply({0, 0, 0}), x = p.apply({1, 0, 0}) - o, y = p.apply({0, 1, 0}) - o, z = p.apply({0, 0, 1}) - o;
    const double det = dot(x, cross(y, z));
    EXPECT_EQ(det < 0, p.flip == 1 || p.flip == 2) << p.flip;
  }
}

TEST(Atlas, SerialisedAtlasReadsBackWithinItsQuantisation) {
  Atlas a;
  a.grid.n = {5, 4, 3};
  a.grid.spacing = 2.5;
  a.grid.origin = {-5, -3.75, -2.5};
  a.cases = 12;
  a.source = "test";
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0, 1);
  for (std::size_t i = 0; i < a.grid.count(); ++i) a.context.push_back(u(rng)), a.mandible.push_back(u(rng));
  const std::vector<std::uint8_t> bytes = serialise(a);
  const Atlas b = deserialise(bytes.data(), bytes.size());
  EXPECT_EQ(b.grid.n, a.grid.n);
  EXPECT_EQ(b.grid.spacing, a.grid.spacing);
  EXPECT_EQ(b.grid.origin, a.grid.origin);
  EXPECT_EQ(b.cases, 12);
  EXPECT_EQ(b.source, "test");
  for (std::size_t i = 0; i < a.grid.count(); ++i) {
    EXPECT_NEAR(b.context[i], a.context[i], 0.5 / 255 + 1e-6);
    EXPECT_NEAR(b.mandible[i], a.mandible[i], 0.5 / 255 + 1e-6);
  }
  std::vector<std::uint8_t> bad = bytes;
  bad.resize(bad.size() / 2);
  EXPECT_THROW(deserialise(bad.data(), bad.size()), Error);
}

TEST(Atlas, ShippedAtlasIsBuiltAndMirrorSymmetric) {
  const Atlas& a = shipped();
  ASSERT_GT(a.cases, 0) << "modules/atlas/mandible_atlas.bin missing: run scripts/build-atlas";
  const Grid& g = a.grid;
  double asym = 0, mass = 0;
  for (int k = 0; k < g.n[2]; ++k)
    for (int j = 0; j < g.n[1]; ++j)
      for (int i = 0; i < g.n[0]; ++i) {
        asym += std::abs(a.mandible[g.linear(i, j, k)] - a.mandible[g.linear(g.n[0] - 1 - i, j, k)]);
        mass += a.mandible[g.linear(i, j, k)];
      }
  EXPECT_LT(asym, 0.01 * mass);
  // The mean mandible's volume lies within the training contours' 29-112 cm3.
  const double cm3 = MandiblePrior(a, Pose{}).mass_mm3() / 1000;
  EXPECT_GT(cm3, 29.0);
  EXPECT_LT(cm3, 112.0);
}

// The sigmoid notch: on a synthetic half-mandible (a ramus splitting at
// level 6 into a condyle to level 9 and a coronoid to level 8), the lowest
// level of the two processes; on the shipped atlas, between the coronoid's
// top and the ramus below, as measured (30 mm: condyle top 39, coronoid 33).
namespace {
Atlas synthetic_half_mandibles() {
  Atlas a;
  a.grid.n = {12, 12, 12};
  a.grid.spacing = 2.0;
  a.grid.origin = {-11.0, -11.0, -4.0};  // x > 0 from i = 6; level k at z = -4 + 2k
  a.mandible.assign(a.grid.count(), 0.0f);
  for (int k = 2; k <= 9; ++k)
    for (int j = 2; j <= 9; ++j) {
      const bool condyle = j >= 7, coronoid = j <= 3;
      if (k >= 6 && !(condyle || coronoid)) continue;  // the notch between them
      if (k > 8 && !condyle) continue;
      for (int i = 7; i <= 9; ++i) a.mandible[a.grid.linear(i, j, k)] = a.mandible[a.grid.linear(11 - i, j, k)] = 0.9f;
    }
  return a;
}
}  // namespace

TEST(Atlas, SigmoidNotchIsTheLowestLevelOfTheTwoProcesses) {
  Atlas a = synthetic_half_mandibles();
  EXPECT_DOUBLE_EQ(sigmoid_notch_height(a), -4.0 + 2.0 * 6);
  for (float& v : a.mandible) v = 0.0f;
  EXPECT_TRUE(std::isnan(sigmoid_notch_height(a)));
  const double shipped_notch = sigmoid_notch_height(shipped());
  EXPECT_GE(shipped_notch, 20.0);
  EXPECT_LE(shipped_notch, 35.0);
}

// The processes' tops: on the synthetic half-mandible, the condyle (behind,
// j 7-9, to level 9) and the coronoid (in front, j 2-3, to level 8), each the
// centroid of its top level; on the shipped atlas the condyle stands behind
// and above the coronoid, as far apart as adult tips across the notch.
TEST(Atlas, ProcessTopsAreTheCondyleBehindAndTheCoronoidInFront) {
  const ProcessTops t = process_tops(synthetic_half_mandibles());
  EXPECT_NEAR(t.condyle[0], 5.0, 1e-9);   // i 7-9: x 3, 5, 7
  EXPECT_NEAR(t.condyle[1], 5.0, 1e-9);   // j 7-9
  EXPECT_NEAR(t.condyle[2], 14.0, 1e-9);  // level 9
  EXPECT_NEAR(t.coronoid[1], -6.0, 1e-9); // j 2-3
  EXPECT_NEAR(t.coronoid[2], 12.0, 1e-9); // level 8
  const ProcessTops s = process_tops(shipped());
  RecordProperty("shipped_condyle_top", std::to_string(s.condyle[1]) + " " + std::to_string(s.condyle[2]));
  RecordProperty("shipped_coronoid_top", std::to_string(s.coronoid[1]) + " " + std::to_string(s.coronoid[2]));
  EXPECT_GT(s.condyle[0], 0.0);
  EXPECT_GT(s.condyle[2], s.coronoid[2]);
  // Condylion to coronoid tip: ~30 mm in adults (minimum ramus breadth 29-33 mm; docs/landmarks.md).
  EXPECT_GT(s.condyle[1] - s.coronoid[1], 20.0);
  EXPECT_LT(s.condyle[1] - s.coronoid[1], 40.0);
}

// The search finds a pose it did not start from: shift, flexion, turn, tilt
// and scale, and tells an upside-down placement from an upright one.
TEST(Atlas, FitRecoversAKnownPoseAndAFlip) {
  Pose truth;
  truth.t = {12, -25, 40};
  truth.pitch = 10 * kDeg, truth.yaw = -6 * kDeg, truth.roll = 4 * kDeg;
  truth.scale = 1.07;
  const Fit f = fit(shipped(), posed_context(truth));
  ASSERT_TRUE(f.found);
  EXPECT_GT(f.ncc, 0.95);
  EXPECT_LT(distance(f.pose.t, truth.t), 3.0);
  EXPECT_NEAR(f.pose.pitch, truth.pitch, 3 * kDeg);
  EXPECT_NEAR(f.pose.yaw, truth.yaw, 3 * kDeg);
  EXPECT_NEAR(f.pose.roll, truth.roll, 3 * kDeg);
  EXPECT_NEAR(f.pose.scale, truth.scale, 0.03);
  EXPECT_LT(f.mirrored_ncc, f.ncc - 0.2);

  Pose upside_down = truth;
  upside_down.flip = 2;  // superior-inferior mirror, as a scan read with the wrong slice order
  const Fit g = fit(shipped(), posed_context(upside_down));
  EXPECT_GT(g.mirrored_ncc, g.ncc + 0.2);
}

// A real scan (OpenKBP pt_245, 4.6 mm): the placed atlas overlaps the
// clinical contour, and the same scan mirrored left-right places it at the
// mirrored position.
TEST(Atlas, RealScanFitsWhereTheContourIsAndMirrorsWithTheScan) {
  const std::string dir = std::string(MANDISYM_SHARED_DATA) + "/openkbp/pt_245";
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << "shared data not present";
  const auto c = ms::testing::load_openkbp(dir);
  const Fit f = fit_ct(c.ct, 250.0);
  ASSERT_TRUE(f.found);
  EXPECT_GT(f.ncc, f.mirrored_ncc + 0.15);
  // Soft Dice of the contour with the placed probability.
  const MandiblePrior prior(shipped(), f.pose);
  const Geometry& g = c.mandible.geom;
  double in = 0, n = 0;
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i)
        if (c.mandible.data[g.linear(i, j, k)]) {
          n += 1;
          in += prior.at(g.index_to_lps(double(i), double(j), double(k)));
        }
  const double agreement = 2 * in * g.voxel_volume_mm3() / (n * g.voxel_volume_mm3() + prior.mass_mm3());
  RecordProperty("agreement", std::to_string(agreement));
  EXPECT_GT(agreement, 0.45);

  Volume flipped = c.ct;
  const Geometry& cg = c.ct.geom;
  for (std::size_t k = 0; k < cg.size[2]; ++k)
    for (std::size_t j = 0; j < cg.size[1]; ++j)
      for (std::size_t i = 0; i < cg.size[0]; ++i) flipped.hu[cg.linear(i, j, k)] = c.ct.hu[cg.linear(cg.size[0] - 1 - i, j, k)];
  const Fit m = fit_ct(flipped, 250.0);
  ASSERT_TRUE(m.found);
  const Vec3 q = cg.lps_to_index(f.pose.t);
  const Vec3 expected = cg.index_to_lps(static_cast<double>(cg.size[0] - 1) - q[0], q[1], q[2]);
  EXPECT_LT(distance(m.pose.t, expected), 1e-6);
  // Symmetrised (fit_ct fits the scan and its mirror): the mirrored scan's
  // fit is the mirror of the fit, to rounding.
  const Pose back = mirror(m.pose, lr_mirror(cg));
  EXPECT_LT(distance(back.t, f.pose.t), 1e-6);
  EXPECT_NEAR(back.pitch, f.pose.pitch, 1e-9);
  EXPECT_NEAR(back.yaw, f.pose.yaw, 1e-9);
  EXPECT_NEAR(back.roll, f.pose.roll, 1e-9);
  EXPECT_NEAR(back.scale, f.pose.scale, 1e-9);
  EXPECT_NEAR(m.ncc, f.ncc, 1e-12);
}

// Storing a scan differently moves nothing but its file's geometry: the same
// voxels turned 10 degrees in their orientation (about their centre) must be
// fitted by the same placement, turned (docs/atlas.md, "The scan's frame").
// Fitted on LPS axes, that turn moved the placement by up to 0.9 mm and,
// through the zone, Cr_L of openkbp-train pt_36 by 20.8 mm.
TEST(Atlas, FitTurnsWithTheScansOrientation) {
  const std::string dir = std::string(MANDISYM_SHARED_DATA) + "/openkbp/pt_245";
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << "shared data not present";
  const auto c = ms::testing::load_openkbp(dir);
  const Fit f = fit_ct(c.ct, 250.0);
  ASSERT_TRUE(f.found);
  const Geometry& g = c.ct.geom;
  const Vec3 pivot = g.index_to_lps(0.5 * (g.size[0] - 1.0), 0.5 * (g.size[1] - 1.0), 0.5 * (g.size[2] - 1.0));
  const double cs = std::cos(10 * kDeg), sn = std::sin(10 * kDeg);
  const double T[9] = {cs, -sn, 0, sn, cs, 0, 0, 0, 1};
  auto turn = [&](const Vec3& p) {
    const Vec3 d = p - pivot;
    return Vec3{T[0] * d[0] + T[1] * d[1] + pivot[0], T[3] * d[0] + T[4] * d[1] + pivot[1], d[2] + pivot[2]};
  };
  Volume stored = c.ct;
  stored.geom.origin = turn(g.origin);
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 3; ++col) {
      double acc = 0;
      for (int k = 0; k < 3; ++k) acc += T[3 * r + k] * g.direction[3 * k + col];
      stored.geom.direction[3 * r + col] = acc;
    }
  const Fit m = fit_ct(stored, 250.0);
  ASSERT_TRUE(m.found);
  EXPECT_NEAR(m.ncc, f.ncc, 1e-6);
  EXPECT_NEAR(m.pose.scale, f.pose.scale, 1e-6);
  for (const Vec3& a : {Vec3{0, 0, 0}, Vec3{40, 0, 30}, Vec3{-40, 20, 30}, Vec3{0, -50, -20}})
    EXPECT_LT(distance(m.pose.apply(a), turn(f.pose.apply(a))), 1e-3) << a[0] << " " << a[1] << " " << a[2];
}

// A scan stored along the LPS axes (any signed permutation) is its own frame.
TEST(Atlas, ScanStoredAlongTheAxesIsItsOwnFrame) {
  Geometry g;
  g.size = {100, 120, 80};
  g.spacing = {0.9, 0.9, 2.5};
  g.origin = {-40, 20, -100};
  g.direction = {-1, 0, 0, 0, 0, 1, 0, 1, 0};
  const ScanFrame f = scan_frame(g);
  for (int i = 0; i < 9; ++i) EXPECT_EQ(f.q[i], i % 4 == 0 ? 1.0 : 0.0);
  EXPECT_TRUE(f.geom.same_grid(g, 1e-12));
  // A turned scan's frame turns its poses with it.
  const double c = std::cos(0.3), s = std::sin(0.3);
  g.direction = {c, -s, 0, s, c, 0, 0, 0, 1};
  const ScanFrame t = scan_frame(g);
  EXPECT_LT(distance(t.to_world(t.geom.index_to_lps(3, 4, 5)), g.index_to_lps(3, 4, 5)), 1e-9);
  Pose p;
  p.t = {5, -7, 9}, p.pitch = 0.2, p.yaw = -0.1, p.roll = 0.05, p.scale = 1.1, p.flip = 1;
  const Pose w = t.to_world(p);
  for (const Vec3& a : {Vec3{10, 0, 0}, Vec3{0, 20, -5}, Vec3{-30, 4, 8}}) EXPECT_LT(distance(w.apply(a), t.to_world(p.apply(a))), 1e-9);
}

// The scan mirror (an array flip about the scan's centre) as a pose map: the
// mirrored placement maps the atlas's own mirror image where the scan
// mirror takes the placement, and mirroring twice gives the pose back.
TEST(Atlas, MirroredPoseIsTheScanMirrorOfThePlacement) {
  Geometry g;
  g.size = {100, 120, 80};
  g.spacing = {0.9, 0.9, 2.5};
  g.origin = {-40, 20, -100};
  const double c = std::cos(0.3), s = std::sin(0.3);
  g.direction = {c, -s, 0, s, c, 0, 0, 0, 1};  // turned 17 degrees about the vertical axis
  const ScanMirror sm = lr_mirror(g);
  EXPECT_EQ(sm.axis, 0);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int n = 0; n < 20; ++n) {
    Pose p;
    p.t = {30 * u(rng), 30 * u(rng), 30 * u(rng)};
    p.pitch = 0.4 * u(rng), p.yaw = 0.4 * u(rng), p.roll = 0.4 * u(rng);
    p.scale = 1.0 + 0.2 * u(rng);
    p.flip = n % 4;
    const Pose m = mirror(p, sm);
    const Vec3 a{60 * u(rng), 60 * u(rng), 60 * u(rng)};
    EXPECT_LT(distance(m.apply({-a[0], a[1], a[2]}), sm.apply(p.apply(a))), 1e-9);
    const Pose back = mirror(m, sm);
    EXPECT_LT(distance(back.apply(a), p.apply(a)), 1e-9);
  }
}

// Two fits of one scan that agree are averaged; a far one loses to the better.
TEST(Atlas, MirrorFitsAreAveragedWhenTheyAgree) {
  Geometry g;
  g.size = {64, 64, 64};
  const ScanMirror sm = lr_mirror(g);
  Fit a;
  a.ncc = 0.8;
  a.pose.t = {10, 0, 0};
  a.pose.yaw = 2 * kDeg;
  Fit b;  // b's pose is in the mirrored scan's frame
  b.ncc = 0.7;
  Pose near = a.pose;
  near.t[1] += 2.0;
  near.yaw += 2 * kDeg;
  b.pose = mirror(near, sm);
  const Fit both = combine_mirror_fits(a, b, sm);
  EXPECT_NEAR(both.ncc, 0.75, 1e-12);
  EXPECT_NEAR(both.pose.t[1], 1.0, 1e-9);
  EXPECT_NEAR(both.pose.yaw, 3 * kDeg, 1e-9);
  EXPECT_TRUE(both.found);
  Pose far = a.pose;
  far.t[2] += 20.0;
  b.pose = mirror(far, sm);
  b.ncc = 0.9;
  const Fit better = combine_mirror_fits(a, b, sm);
  EXPECT_NEAR(better.ncc, 0.9, 1e-12);
  EXPECT_LT(distance(better.pose.t, far.t), 1e-9);
}
