// Symmetry plane and mirror-distance asymmetry on the phantom matrix (issue
// E): ground-truth mandible masks -> surface -> detected landmarks ->
// reference::fit -> mirror distance and bilateral measures.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "asymmetry/measures.h"
#include "asymmetry/saf.h"
#include "landmarks/landmarks.h"
#include "phantom/phantom.h"
#include "reference/reference.h"
#include "pipeline/cranial.h"
#include "surface/surface.h"

namespace {

using ms::Vec3;
using ms::operator+;
using ms::operator*;

struct Case {
  const char* name;
  double yaw, pitch, roll;
  double ramus_L;  // imposed elongation, mm
  bool mirror;
  double body_L = 0;  // imposed body lengthening, mm
  double chin = 0;    // imposed chin deviation towards the left, mm
};

struct Outcome {
  ms::phantom::Phantom ph;
  ms::reference::Result ref;
  ms::asymmetry::MirrorResult mirror;
  std::map<std::string, ms::asymmetry::Bilateral> bilateral;
  double angle_deg = 0, offset_mm = 0;
};

// 1 mm phantom of the case, noise-free (the ground-truth mask is meshed).
ms::phantom::Phantom phantom(const Case& c) {
  ms::phantom::PhantomParams p;
  p.spacing = {1, 1, 1};
  p.fov_mm = {150, 140, 130};
  p.noise_hu = 0;
  p.yaw_deg = c.yaw;
  p.pitch_deg = c.pitch;
  p.roll_deg = c.roll;
  p.side[0].ramus_height_mm = c.ramus_L;
  p.side[0].body_length_mm = c.body_L;
  p.chin_deviation_mm = c.chin;
  p.mirror = c.mirror;
  return ms::phantom::generate(p);
}

Outcome run(const Case& c) {
  Outcome o;
  o.ph = phantom(c);
  const auto surf = ms::surface::mesh_from_mask(o.ph.mandible);
  // The pipeline's head frame: the mandible's plane and the palatal plane.
  ms::landmarks::PalatalPlane palate;
  const auto lm = ms::landmarks::detect_in_head_frame(o.ph.ct, surf.mesh, {}, {}, &palate);
  ms::reference::Options ro;
  ro.superior = palate.found ? palate.superior : ms::Vec3{0, 0, 1};
  const auto t0 = std::chrono::steady_clock::now();
  o.ref = ms::reference::fit(lm.landmarks, &surf.mesh, ro);
  const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  o.angle_deg = std::acos(std::min(1.0, std::abs(ms::dot(o.ref.plane.normal, o.ph.plane.normal)))) * 180.0 / M_PI;
  o.offset_mm = std::abs(o.ref.plane.signed_distance(o.ph.plane.point));
  const auto regions = ms::asymmetry::assign_regions(surf.mesh, lm.landmarks);
  o.mirror = ms::asymmetry::mirror_distance(surf.mesh, o.ref.plane, regions, &lm.landmarks);
  o.bilateral = ms::asymmetry::bilateral_measures(lm.landmarks, o.ref.plane);
  const auto rh = o.bilateral.find("ramus_height_mm");
  std::printf("%s: plane %.2f deg %.2f mm, mean|d| %.3f mm, ramus L-R %+.2f mm, fit %.2f s (%zu vertices)\n", c.name, o.angle_deg,
              o.offset_mm, o.mirror.overall.mean_abs, rh == o.bilateral.end() ? 0.0 : rh->second.diff, t, surf.mesh.vertices.size());
  return o;
}

class SymmetricPhantom : public ::testing::TestWithParam<Case> {};

TEST_P(SymmetricPhantom, PlaneAndMirrorDistanceAreExact) {
  const Outcome o = run(GetParam());
  EXPECT_LE(o.angle_deg, 1.0);
  EXPECT_LE(o.offset_mm, 0.5);
  EXPECT_LE(o.mirror.overall.mean_abs, 0.3);
  ASSERT_TRUE(o.bilateral.count("ramus_height_mm"));
  // A symmetric mandible's ramus difference is the two sides' landmark noise
  // at 1 mm voxels. Gonion follows each side's own tangents, whose
  // directions the staircase turns by ~0.5 degrees about the condyle: T and
  // the bisector's crossing move by ~0.5 mm (docs/landmarks.md, "Why the
  // bisector is followed"). Measured: 0.07-0.30 mm on these five poses
  // (with each side's longest hull edge and the crossing's nearest vertex,
  // 1.19 mm on "mixed"). Bound: 0.6 voxel.
  EXPECT_LT(std::abs(o.bilateral.at("ramus_height_mm").diff), 0.6);
}

INSTANTIATE_TEST_SUITE_P(Poses, SymmetricPhantom,
                         ::testing::Values(Case{"neutral", 0, 0, 0, 0, false}, Case{"yaw15", 15, 0, 0, 0, false},
                                           Case{"roll_m15", 0, 0, -15, 0, false}, Case{"mixed", 10, -8, 6, 0, false},
                                           Case{"yaw_m20_pitch5", -20, 5, 0, 0, false}),
                         [](const ::testing::TestParamInfo<Case>& i) { return std::string(i.param.name); });

class GradedRamus : public ::testing::TestWithParam<Case> {};

// Left ramus elongated by 2, 4, 6 mm (mirrored: the right one). The condyle
// region's largest |mirror distance| must match the imposed elongation, the
// bulging side must be the modified one (signed distance at its condylion),
// and the bilateral ramus height difference must match both the imposed
// elongation and the phantom's own Co-Go difference.
TEST_P(GradedRamus, CondyleDistanceAndRamusDifferenceMatchTheImposedChange) {
  const Case& c = GetParam();
  const Outcome o = run(c);
  const std::string mod = c.mirror ? "_R" : "_L", other = c.mirror ? "_L" : "_R";
  const double cmax = o.mirror.regions.at("condyle" + mod).max;
  const double truth = o.ph.truth.ramus_height_L - o.ph.truth.ramus_height_R;
  const double diff = o.bilateral.at("ramus_height_mm").diff;
  std::printf("  condyle%s max %.2f mm (imposed %.1f); at Co%s %+.2f, Co%s %+.2f; ramus diff %.2f (truth %.2f)\n", mod.c_str(),
              cmax, c.ramus_L, mod.c_str(), o.mirror.at_landmarks.at("Co" + mod), other.c_str(),
              o.mirror.at_landmarks.at("Co" + other), diff, truth);
  // The phantom's knob raises the condylion by exactly that many mm along the
  // ramus axis, so it is the imposed value for both numbers.
  EXPECT_NEAR(cmax, c.ramus_L, 0.5);
  EXPECT_GT(o.mirror.at_landmarks.at("Co" + mod), 0.5 * c.ramus_L);
  EXPECT_LT(o.mirror.at_landmarks.at("Co" + other), -0.5 * c.ramus_L);
  EXPECT_NEAR(diff, truth, 0.5);
  EXPECT_NEAR(std::abs(diff), c.ramus_L, 0.5);
  EXPECT_LE(o.angle_deg, 1.0);
}

INSTANTIATE_TEST_SUITE_P(Series, GradedRamus,
                         ::testing::Values(Case{"ramus2", 0, 0, 0, 2, false}, Case{"ramus4", 0, 0, 0, 4, false},
                                           Case{"ramus6", 0, 0, 0, 6, false}, Case{"ramus6_posed_mirror", 8, 6, -5, 6, true},
                                           Case{"ramus4_posed", -12, 0, 10, 4, false}),
                         [](const ::testing::TestParamInfo<Case>& i) { return std::string(i.param.name); });

}  // namespace

// ---- SAF score on a graded series (issue F), the pipeline's own chain:
// detected landmarks -> reference configuration -> SAF with disks at it.
namespace {
struct SafOutcome {
  double score = 0;
  std::string largest_sided;  // region with the largest mean of the lateral SAF map
};

SafOutcome saf_outcome(const Case& c) {
  const auto ph = phantom(c);
  const auto surf = ms::surface::mesh_from_mask(ph.mandible);
  const auto lm = ms::landmarks::detect_in_head_frame(ph.ct, surf.mesh);
  const auto ref = ms::reference::fit(lm.landmarks, &surf.mesh);
  const auto r =
      ms::asymmetry::compute_saf(surf.mesh, ms::asymmetry::saf_anchors(lm.landmarks, ref.reference), ref.plane);
  const auto regions = ms::asymmetry::assign_regions(surf.mesh, lm.landmarks);
  const auto mirror = ms::asymmetry::mirror_distance(surf.mesh, ref.plane, regions);
  const auto means = ms::asymmetry::regional_means(ms::asymmetry::lateral_map(r.per_vertex, mirror),
                                                   ms::asymmetry::vertex_areas(surf.mesh), regions);
  SafOutcome o{r.score, ms::asymmetry::largest_region(means)};
  std::printf("%s: SAF %.4f rad, lateral map largest in %s (%.4f)\n", c.name, r.score, o.largest_sided.c_str(),
              o.largest_sided.empty() ? 0.0 : means.at(o.largest_sided));
  return o;
}
double saf_score(const Case& c) { return saf_outcome(c).score; }

// METHOD.md §7: the side with the larger imposed change is the side the maps
// point to. The symmetrised SAF map cannot (a vertex and its mirror point
// carry the same value); its lateral form (asymmetry::lateral_map) must.
void expect_on_side(const SafOutcome& o, const std::string& side, const std::string& what) {
  EXPECT_GE(o.largest_sided.size(), 2u) << what;
  if (o.largest_sided.size() >= 2) EXPECT_EQ(o.largest_sided.substr(o.largest_sided.size() - 2), side) << what;
}
}  // namespace

TEST(SafPhantoms, GradedRamusIsOrderedAndSeparatedFromSymmetric) {
  // Posed (8, 6, -5) so that the voxel surface is not trivially symmetric.
  std::vector<double> s;
  for (double k : {0.0, 2.0, 4.0, 6.0}) {
    const SafOutcome o = saf_outcome(Case{"ramus", 8, 6, -5, k, false});
    s.push_back(o.score);
    if (k > 0) expect_on_side(o, "_L", "ramus +" + std::to_string(k));
  }
  for (std::size_t i = 1; i < s.size(); ++i) EXPECT_GT(s[i], s[i - 1]) << "ramus +" << 2 * i << " mm";
  EXPECT_GT(s[1], 1.4 * s[0]);  // +2 mm clearly above the symmetric floor (measured 0.0151 vs 0.0066)
  // Mirrored input (METHOD.md §7): the same phantom reflected left<->right
  // scores the same within 1 % (the target). The flipped mask meshes
  // to the mirror image of the same mesh (the surface's canonical
  // orientation); before it, decimation and remeshing gave another
  // triangulation and the score moved by 1-3 % here (docs/method.md).
  const SafOutcome m4 = saf_outcome(Case{"ramus4_mirrored", 8, 6, -5, 4, true});
  EXPECT_NEAR(m4.score, s[2], 0.01 * s[2]);
  // The sided map now points to the right side.
  expect_on_side(m4, "_R", "ramus +4 mirrored");
}

namespace {
TEST(SafPhantoms, GradedBodyAndChinAreOrderedAndAboveSymmetric) {
  // Neutral pose; measured symmetric 0.0013, body +2/4/6 0.026/0.079/0.097,
  // chin 0.048/0.105/0.170 (docs/method.md). The body knob moves one angle,
  // ramus and condyle back (one side), so the lateral map must point to it; the
  // chin knob shifts the symphysis to the left, tapering to zero at both
  // angles: the left body shortens and the right lengthens by about as much,
  // and the map points to the larger, lengthened side (docs/method.md).
  const double sym = saf_score(Case{"symmetric", 0, 0, 0, 0, false});
  for (const char* kind : {"body", "chin"}) {
    std::vector<double> s;
    for (double k : {2.0, 4.0, 6.0}) {
      Case c{kind, 0, 0, 0, 0, false};
      const bool body = std::string(kind) == "body";
      (body ? c.body_L : c.chin) = k;
      const SafOutcome o = saf_outcome(c);
      s.push_back(o.score);
      expect_on_side(o, body ? "_L" : "_R", std::string(kind) + " +" + std::to_string(k));
    }
    EXPECT_GT(s[0], 2 * sym) << kind << " +2 mm";
    for (std::size_t i = 1; i < s.size(); ++i) EXPECT_GT(s[i], s[i - 1]) << kind << " +" << 2 * (i + 1) << " mm";
  }
}
// Cranial mid-sagittal plane: the skull's own mirror plane stays on the true
// mid-sagittal plane whatever the mandible does; a chin deviated 4 mm to the
// left then sits 4 mm left of it, while the mandible's own plane leans
// towards the deviation (shape asymmetry is partly absorbed by it).
class CranialPlane : public ::testing::TestWithParam<Case> {};

TEST_P(CranialPlane, StaysOnTheTrueMidSagittalPlaneAndMeasuresTheChinAgainstIt) {
  const Case& c = GetParam();
  const Outcome o = run(c);
  ms::pipeline::CranialInputs ci;
  ci.ct = &o.ph.ct;
  ci.mandible = &o.ph.mandible;
  ci.mandible_plane = o.ref.plane;
  ci.landmarks = o.ph.landmarks;  // true condylions for the floor, true Me measured
  const auto cr = ms::pipeline::fit_cranial_plane(ci);
  ASSERT_TRUE(cr.found) << cr.reason;
  const double angle = std::acos(std::min(1.0, std::abs(ms::dot(cr.plane.normal, o.ph.plane.normal)))) * 180.0 / M_PI;
  const double offset = std::abs(cr.plane.signed_distance(o.ph.plane.point));
  const double me = cr.to_cranial_mm.at("Me"), me_own = cr.to_mandible_mm.at("Me");
  std::printf("  cranium %.0f cm3, plane %.3f deg %.3f mm from the truth (rms %.2f mm), %.2f deg to the mandible's; Me %+.2f mm "
              "to the cranial plane, %+.2f to the mandible's\n",
              cr.bone_volume_cm3, angle, offset, cr.surface_rms_mm, cr.angle_to_mandible_plane_deg, me, me_own);
  // Measured 0.016-0.11 deg, 0.006-0.03 mm on 1 mm blocks; the 2 mm blocks
  // it replaced were 0.27-0.40 deg off on the posed cases (docs/method.md).
  EXPECT_LE(angle, 0.2);
  EXPECT_LE(offset, 0.2);
  EXPECT_NEAR(me, c.mirror ? -c.chin : c.chin, 0.5);
  if (c.chin > 0) EXPECT_LT(std::abs(me_own), std::abs(me) - 0.5);
}

INSTANTIATE_TEST_SUITE_P(Poses, CranialPlane,
                         ::testing::Values(Case{"symmetric_posed", 10, -6, 4, 0, false},
                                           Case{"chin4", 0, 0, 0, 0, false, 0, 4},
                                           Case{"chin4_posed_mirror", -12, 8, -6, 0, true, 0, 4}),
                         [](const ::testing::TestParamInfo<Case>& i) { return std::string(i.param.name); });

}  // namespace
