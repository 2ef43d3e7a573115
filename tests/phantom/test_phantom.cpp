// The phantom is the project's ground truth: its landmarks must sit on its
// mask, its knobs must do what they say, and it must be deterministic.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/digest.h"
#include "phantom/phantom.h"

using namespace ms;
using phantom::PhantomParams;

namespace {

PhantomParams small() {
  PhantomParams p;
  p.spacing = {1.0, 1.0, 1.0};
  p.fov_mm = {140, 130, 130};
  return p;
}

// Smallest distance from p to a face between a mask voxel and a non-mask voxel.
double distance_to_mask_boundary(const Mask& m, const Vec3& p) {
  const Geometry& g = m.geom;
  const Vec3 c = g.lps_to_index(p);
  const long r = 4;
  double best = std::numeric_limits<double>::infinity();
  for (long k = std::lround(c[2]) - r; k <= std::lround(c[2]) + r; ++k)
    for (long j = std::lround(c[1]) - r; j <= std::lround(c[1]) + r; ++j)
      for (long i = std::lround(c[0]) - r; i <= std::lround(c[0]) + r; ++i) {
        if (i < 1 || j < 1 || k < 1 || i + 1 >= long(g.size[0]) || j + 1 >= long(g.size[1]) || k + 1 >= long(g.size[2]))
          continue;
        if (!m.data[g.linear(i, j, k)]) continue;
        const long nb[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
        for (const auto& d : nb) {
          if (m.data[g.linear(i + d[0], j + d[1], k + d[2])]) continue;
          const Vec3 face = g.index_to_lps(i + 0.5 * d[0], j + 0.5 * d[1], k + 0.5 * d[2]);
          best = std::min(best, distance(face, p));
        }
      }
  return best;
}

void expect_landmarks_on_surface(const phantom::Phantom& ph) {
  const double s = std::max({ph.params.spacing[0], ph.params.spacing[1], ph.params.spacing[2]});
  ASSERT_EQ(ph.landmarks.points.size(), landmark_names().size());
  for (const auto& [name, p] : ph.landmarks.points) {
    const double d = distance_to_mask_boundary(ph.mandible, p);
    // A point on the implicit surface is within half a voxel diagonal of a
    // boundary face centre; allow one voxel.
    EXPECT_LE(d, s) << name << " is " << d << " mm from the mask surface";
  }
}

}  // namespace

TEST(Phantom, GroundTruthLandmarksLieOnTheMaskSurface) { expect_landmarks_on_surface(phantom::generate(small())); }

TEST(Phantom, LandmarksStayOnSurfaceUnderPoseAndAsymmetry) {
  PhantomParams p = small();
  p.yaw_deg = 12;
  p.pitch_deg = -9;
  p.roll_deg = 6;
  p.shift_mm = {4, -3, 5};
  p.side[1].ramus_height_mm = 5;
  p.side[0].gonial_angle_deg = 6;
  p.chin_deviation_mm = 2;
  expect_landmarks_on_surface(phantom::generate(p));
}

TEST(Phantom, SymmetricPhantomLandmarksMirrorThroughTruePlane) {
  PhantomParams p = small();
  p.yaw_deg = -7;
  p.roll_deg = 4;
  const auto ph = phantom::generate(p);
  for (const char* n : {"Co", "Cr", "Go"}) {
    const Vec3 l = *ph.landmarks.find(std::string(n) + "_L"), r = *ph.landmarks.find(std::string(n) + "_R");
    EXPECT_LT(distance(ph.plane.reflect(l), r), 0.3) << n;
    EXPECT_GT(ph.plane.signed_distance(l), 20.0) << n << "_L must be on the patient's left";
  }
  for (const char* n : {"Me", "Pog"}) EXPECT_LT(std::abs(ph.plane.signed_distance(*ph.landmarks.find(n))), 0.3) << n;
  EXPECT_NEAR(norm(ph.plane.normal), 1.0, 1e-12);
}

TEST(Phantom, DeterministicForASeed) {
  PhantomParams p = small();
  p.fov_mm = {100, 100, 80};
  p.seed = 42;
  const auto a = phantom::generate(p), b = phantom::generate(p);
  EXPECT_EQ(sha256_hex(a.ct.hu.data(), a.ct.hu.size() * 4), sha256_hex(b.ct.hu.data(), b.ct.hu.size() * 4));
  p.seed = 43;
  const auto c = phantom::generate(p);
  EXPECT_NE(sha256_hex(a.ct.hu.data(), a.ct.hu.size() * 4), sha256_hex(c.ct.hu.data(), c.ct.hu.size() * 4));
  EXPECT_EQ(a.mandible.data, c.mandible.data);  // noise does not move anatomy
}

TEST(Phantom, TissueValuesArePlausibleCt) {
  PhantomParams p = small();
  p.noise_hu = 0;
  p.blur_mm = 0;
  const auto ph = phantom::generate(p);
  const Geometry& g = ph.ct.geom;
  // Air outside the head, soft tissue, cortical and cancellous bone, enamel.
  EXPECT_NEAR(ph.ct.hu[g.linear(0, 0, 0)], -1000.0f, 1.0f);
  double mn = 1e9, mx = -1e9;
  std::size_t cancellous = 0, cortical = 0;
  for (std::size_t i = 0; i < ph.ct.hu.size(); ++i) {
    if (!ph.mandible.data[i]) continue;
    mn = std::min<double>(mn, ph.ct.hu[i]);
    mx = std::max<double>(mx, ph.ct.hu[i]);
    cancellous += std::abs(ph.ct.hu[i] - 350.0f) < 5;
    cortical += std::abs(ph.ct.hu[i] - 1600.0f) < 5;
  }
  EXPECT_GT(cancellous, 1000u);
  EXPECT_GT(cortical, 1000u);
  EXPECT_GE(mx, 2500);  // tooth crowns
  const double vol_cm3 = ph.mandible.count() * g.voxel_volume_mm3() / 1000.0;
  EXPECT_GT(vol_cm3, 45.0);  // adult mandible incl. teeth: tens of cm3
  EXPECT_LT(vol_cm3, 110.0);
}

TEST(Phantom, RamusKnobLengthensOnlyThatSide) {
  PhantomParams p = small();
  const auto base = phantom::generate(p);
  p.side[0].ramus_height_mm = 4;
  const auto mod = phantom::generate(p);
  EXPECT_NEAR(base.truth.ramus_height_L, base.truth.ramus_height_R, 0.3);
  const double grow = mod.truth.ramus_height_L - base.truth.ramus_height_L;
  EXPECT_GT(grow, 3.5);  // the condyle rises 4 mm; Co-Go is slightly oblique to it
  EXPECT_LT(grow, 4.5);
  // The condylion moves by exactly the knob (along the ramus axis, tilted back).
  const Vec3 d = *mod.landmarks.find("Co_L") - *base.landmarks.find("Co_L");
  EXPECT_NEAR(ms::norm(d), 4.0, 0.1);
  EXPECT_GT(d[2], 3.8);
  EXPECT_NEAR(mod.truth.ramus_height_R, base.truth.ramus_height_R, 0.3);
  EXPECT_GT(mod.mandible.count(), base.mandible.count());
}

TEST(Phantom, BodyAndChinKnobs) {
  PhantomParams p = small();
  const auto base = phantom::generate(p);
  p.side[1].body_length_mm = 5;
  const auto body = phantom::generate(p);
  EXPECT_GT(body.truth.body_length_R - base.truth.body_length_R, 3.0);
  EXPECT_NEAR(body.truth.body_length_L, base.truth.body_length_L, 1.0);
  PhantomParams q = small();
  q.chin_deviation_mm = 4;
  const auto chin = phantom::generate(q);
  EXPECT_NEAR((*chin.landmarks.find("Me"))[0] - (*base.landmarks.find("Me"))[0], 4.0, 0.6);
  EXPECT_NEAR((*chin.landmarks.find("Pog"))[0] - (*base.landmarks.find("Pog"))[0], 4.0, 0.6);
}

TEST(Phantom, MirrorFlipsVolumeAndSwapsLabels) {
  PhantomParams p = small();
  p.fov_mm = {140, 110, 110};
  p.side[0].ramus_height_mm = 4;
  p.yaw_deg = 5;
  const auto a = phantom::generate(p);
  p.mirror = true;
  const auto m = phantom::generate(p);
  const Geometry& g = a.ct.geom;
  for (std::size_t k = 0; k < g.size[2]; k += 7)
    for (std::size_t j = 0; j < g.size[1]; j += 5)
      for (std::size_t i = 0; i < g.size[0]; i += 3)
        ASSERT_EQ(a.ct.hu[g.linear(i, j, k)], m.ct.hu[g.linear(g.size[0] - 1 - i, j, k)]);
  const double xc = g.index_to_lps(0.5 * (g.size[0] - 1), 0, 0)[0];
  const Vec3 co = *a.landmarks.find("Co_L"), mco = *m.landmarks.find("Co_R");
  EXPECT_NEAR(mco[0], 2 * xc - co[0], 1e-9);
  EXPECT_NEAR(mco[2], co[2], 1e-9);
  EXPECT_EQ(m.truth.side[1].ramus_height_mm, 4);  // the elongated side is now the right
  EXPECT_NEAR(m.truth.ramus_height_R, a.truth.ramus_height_L, 1e-9);
  EXPECT_GT(m.plane.normal[0], 0.9);  // still points to the patient's left
}

// Edentulous: no crowns anywhere (nothing above cortical bone's 1600 HU),
// the mandible smaller by its teeth, metal refused (the fillings sit in teeth).
TEST(Phantom, EdentulousJawsHaveNoTeeth) {
  PhantomParams p = small();
  p.noise_hu = 0;
  p.blur_mm = 0;
  const auto dentate = phantom::generate(p);
  p.edentulous = true;
  const auto ph = phantom::generate(p);
  EXPECT_LE(*std::max_element(ph.ct.hu.begin(), ph.ct.hu.end()), 1700.0f);
  EXPECT_GE(*std::max_element(dentate.ct.hu.begin(), dentate.ct.hu.end()), 2500.0f);
  const double lost = 1.0 - static_cast<double>(ph.mandible.count()) / static_cast<double>(dentate.mandible.count());
  EXPECT_GT(lost, 0.03);  // lower crowns: a few cm3
  EXPECT_LT(lost, 0.25);
  p.metal = true;
  EXPECT_THROW(phantom::generate(p), std::invalid_argument);
}

// --scale shrinks the whole anatomy about the point between the condylar
// heads (the plane's point): every landmark's offset from it scales, the
// mask's volume with the cube, and the landmarks stay on the mask.
TEST(Phantom, ScaleShrinksTheWholeAnatomyAboutTheCondyles) {
  PhantomParams p = small();
  p.noise_hu = 0;
  const auto adult = phantom::generate(p);
  p.scale = 0.7;
  const auto child = phantom::generate(p);
  expect_landmarks_on_surface(child);
  // The grid is centred on the scaled pivot, so the condyles' midpoint scales about LPS 0 as well.
  EXPECT_LT(distance(child.plane.point, 0.7 * adult.plane.point), 1e-9);
  for (const auto& [name, q] : adult.landmarks.points) {
    const Vec3* c = child.landmarks.find(name);
    ASSERT_NE(c, nullptr) << name;
    const Vec3 want = adult.plane.point + 0.7 * (q - adult.plane.point);
    EXPECT_LT(distance(*c - child.plane.point, want - adult.plane.point), 1e-6) << name;
  }
  const double ratio = static_cast<double>(child.mandible.count()) / static_cast<double>(adult.mandible.count());
  EXPECT_NEAR(ratio, 0.343, 0.02);
  p.scale = 0.5;
  EXPECT_THROW(phantom::generate(p), std::invalid_argument);
}

TEST(Phantom, RejectsInvalidParameters) {
  PhantomParams p = small();
  p.spacing = {0.0, 1, 1};
  EXPECT_THROW(phantom::generate(p), std::invalid_argument);
  p = small();
  p.side[0].ramus_height_mm = 40;
  EXPECT_THROW(phantom::generate(p), std::invalid_argument);
  p = small();
  p.noise_hu = -1;
  EXPECT_THROW(phantom::generate(p), std::invalid_argument);
}
