// Landmark detection on the phantom matrix (issue D): ground-truth mandible
// masks of posed, asymmetric and mirrored phantoms -> surface -> detector,
// errors against the phantom's analytic landmarks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>

#include "landmarks/landmarks.h"
#include "landmarks/palate.h"
#include "phantom/phantom.h"
#include "surface/surface.h"

namespace {

using ms::Vec3;
using ms::operator-;

struct Case {
  const char* name;
  double yaw, pitch, roll;
  bool mirror;
  double ramus_L;  // mm
  double spacing;
  double gonial_L = 0;  // degrees (opening the angle tilts the ramus back)
  double scale = 1;     // size of the head model (0.7: a young child's mandible)
};

std::ostream& operator<<(std::ostream& o, const Case& c) { return o << c.name; }

// Errors of one case; also accumulated for the matrix summary.
std::map<std::string, std::vector<double>>& all_errors() {
  static std::map<std::string, std::vector<double>> e;
  return e;
}

class LandmarkMatrix : public ::testing::TestWithParam<Case> {};

TEST_P(LandmarkMatrix, LabelsEveryLandmarkOnTheRightSideNearTheTruth) {
  const Case& c = GetParam();
  ms::phantom::PhantomParams p;
  p.spacing = {c.spacing, c.spacing, c.spacing};
  p.fov_mm = {150, 140, 130};
  p.yaw_deg = c.yaw;
  p.pitch_deg = c.pitch;
  p.roll_deg = c.roll;
  p.mirror = c.mirror;
  p.side[0].ramus_height_mm = c.ramus_L;
  p.side[0].gonial_angle_deg = c.gonial_L;
  p.scale = c.scale;
  p.occlusal_gap_mm = 2;
  p.noise_hu = 0;
  const auto ph = ms::phantom::generate(p);
  const auto surf = ms::surface::mesh_from_mask(ph.mandible);
  // The head frame as the pipeline builds it: the mandible's symmetry plane
  // and the palatal plane from the CT.
  ms::landmarks::PalatalPlane palate;
  const auto r = ms::landmarks::detect_in_head_frame(ph.ct, surf.mesh, {}, {}, &palate);
  ASSERT_TRUE(palate.found) << palate.reason;
  const double frame_err = std::acos(std::min(1.0, ms::dot(palate.superior, ph.superior))) * 180 / M_PI;
  std::printf("%s: palate tilt %.2f deg (head pitch %.0f), superior %.2f deg from the head's, %zu samples over %.0f mm, rms %.2f mm\n",
              c.name, palate.tilt_deg, c.pitch, frame_err, palate.samples, palate.length_mm, palate.rms_mm);
  EXPECT_LT(frame_err, 1.0);
  EXPECT_TRUE(r.missing.empty()) << r.missing.size() << " missing";
  std::string line;
  for (const auto& name : ms::landmark_names()) {
    const Vec3* got = r.landmarks.find(name);
    const Vec3* want = ph.landmarks.find(name);
    ASSERT_NE(want, nullptr) << name;
    if (!got) continue;
    const double e = ms::norm(*got - *want);
    all_errors()[name.substr(0, 2)].push_back(e);
    char buf[48];
    std::snprintf(buf, sizeof buf, " %s %.1f", name.c_str(), e);
    if (std::getenv("LM_VEC")) std::printf("  %s d = %.1f %.1f %.1f\n", name.c_str(), (*got)[0] - (*want)[0], (*got)[1] - (*want)[1], (*got)[2] - (*want)[2]);
    line += buf;
    // Side: bilateral labels on the patient's side of the true plane.
    if (name.size() > 2 && name[2] == '_') {
      const double side = ms::dot(*got - ph.plane.point, ph.plane.normal);
      EXPECT_GT(name[3] == 'L' ? side : -side, 10.0) << name << " on the wrong side";
    }
    // Yaw and roll are corrected by the mandible's own symmetry plane, pitch
    // by the palatal plane: every pose is held to the same tolerance (the
    // targets are matrix means of 1.5 mm, 2.5 mm for Go).
    EXPECT_LT(e, 2.0) << name;
  }
  std::printf("%s:%s\n", c.name, line.c_str());
}

INSTANTIATE_TEST_SUITE_P(
    Phantoms, LandmarkMatrix,
    ::testing::Values(Case{"neutral", 0, 0, 0, false, 0, 1.0}, Case{"yaw_p20", 20, 0, 0, false, 0, 1.0},
                      Case{"yaw_m20", -20, 0, 0, false, 0, 1.0}, Case{"pitch_p20", 0, 20, 0, false, 0, 1.0},
                      Case{"pitch_m20", 0, -20, 0, false, 0, 1.0}, Case{"roll_p20", 0, 0, 20, false, 0, 1.0},
                      Case{"roll_m20", 0, 0, -20, false, 0, 1.0}, Case{"combined", 12, -10, 8, false, 0, 1.0},
                      Case{"ramusL4", 0, 0, 0, false, 4, 1.0}, Case{"ramusL4_mirror", 0, 0, 0, true, 4, 1.0},
                      Case{"ramusL6_posed_mirror", -10, 8, -6, true, 6, 1.0}, Case{"fine_0_8mm", 5, 5, 5, false, 2, 0.8},
                      // Opened 10 degrees: the truth's gonion was half-way up the ramus
                      // (22 mm off) until both sides classified each hull edge one way.
                      Case{"gonialL10", 0, 0, 0, false, 0, 1.0, 10},
                      // Beyond the poses above: turned 45 degrees (the mirror-ICP from the
                      // scan's x axis went elsewhere, no left/right pair) and pitched 40
                      // degrees (the nasal floor tilted 40, beyond the 35 degree search).
                      Case{"yaw_p45", 45, 0, 0, false, 0, 1.0}, Case{"pitch_p40", 0, 40, 0, false, 0, 1.0},
                      // A small child's mandible (0.65 of the adult model): Go_R was missing
                      // while the gonial tangents had to be 15 mm long, not a fifth of the side.
                      Case{"child_0_65", 0, 0, 0, false, 0, 1.0, 0, 0.65},
                      Case{"child_0_75_posed_ramusL3", 8, 6, -5, false, 3, 1.0, 0, 0.75}),
    [](const ::testing::TestParamInfo<Case>& i) { return std::string(i.param.name); });

}  // namespace

namespace {

// A scan whose upper edge cuts the condyles: Co is reported missing rather
// than placed on the cut, while the chin landmarks are still found.
// The landmarks of a noise-free 1 mm phantom's ground-truth surface, detected
// knowing the scan's grid (which cuts the mandible).
struct CutScan {
  ms::phantom::Phantom ph;
  ms::Mesh mesh;
  ms::landmarks::Result r;
};
CutScan landmarks_on_cut_scan(const ms::Vec3& fov, const ms::Vec3& shift) {
  ms::phantom::PhantomParams p;
  p.spacing = {1, 1, 1};
  p.fov_mm = fov;
  p.shift_mm = shift;
  p.noise_hu = 0;
  CutScan c;
  c.ph = ms::phantom::generate(p);
  c.mesh = ms::surface::mesh_from_mask(c.ph.mandible).mesh;
  ms::landmarks::Options o;
  o.scan_grid = &c.ph.mandible.geom;
  c.r = ms::landmarks::detect(c.mesh, o);
  return c;
}

TEST(Landmarks, TruncatedCondylesAreMissingNotGuessed) {
  // Head moved up: the grid's top cuts through the condylar necks.
  const CutScan c = landmarks_on_cut_scan({150, 140, 130}, {0, 0, 52});
  const auto& r = c.r;
  EXPECT_FALSE(r.landmarks.has("Co_L"));
  EXPECT_FALSE(r.landmarks.has("Co_R"));
  EXPECT_TRUE(r.landmarks.has("Me"));
  EXPECT_TRUE(r.landmarks.has("Pog"));
  for (const char* n : {"Co_L", "Co_R"}) {
    ASSERT_TRUE(r.why_missing.count(n)) << n;
    EXPECT_NE(r.why_missing.at(n).find("edge of the scan"), std::string::npos) << r.why_missing.at(n);
  }
  EXPECT_EQ(r.cut_at, std::vector<std::string>{"top"});
  // Without the scan grid the detector cannot know, and places them.
  const auto blind = ms::landmarks::detect(c.mesh);
  EXPECT_TRUE(blind.landmarks.has("Co_L"));
  EXPECT_TRUE(blind.cut_at.empty());
}

// Landmarks of the noise-free 1 mm phantom with its left condylar process
// taken out of the mask down to `below_mm` under the lower of its two process
// tips: every voxel of the left side closer to the condylion than to the
// coronoid tip.
struct LostCondyle {
  Vec3 cr, co_r, cr_r;
  ms::landmarks::Result r;
};
LostCondyle landmarks_without_left_condyle(double below_mm) {
  ms::phantom::PhantomParams p;
  p.spacing = {1, 1, 1};
  p.fov_mm = {150, 140, 130};
  p.noise_hu = 0;
  auto ph = ms::phantom::generate(p);
  const Vec3 co = *ph.landmarks.find("Co_L"), cr = *ph.landmarks.find("Cr_L");
  const auto& g = ph.mandible.geom;
  const double floor_h = std::min(ms::dot(co, ph.superior), ms::dot(cr, ph.superior)) - below_mm;
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        auto& m = ph.mandible.data[g.linear(i, j, k)];
        const Vec3 x = g.index_to_lps(double(i), double(j), double(k));
        const bool left = x[0] > co[0] - 30;  // LPS +x is the patient's left; the half-width is ~50 mm
        if (left && ms::dot(x, ph.superior) > floor_h && ms::norm(x - co) < ms::norm(x - cr)) m = 0;
      }
  return {cr, *ph.landmarks.find("Co_R"), *ph.landmarks.find("Cr_R"),
          ms::landmarks::detect(ms::surface::mesh_from_mask(ph.mandible).mesh)};
}

// The condylar process left out of the mask (as when a condylar head fused
// to the skull base at 4 mm voxels leaves the segmentation with its neck):
// the ramus's processes are the coronoid and, cut 20 mm down, a stump on the
// posterior border. Cr_L is the coronoid, and Co_L is missing with the
// reason, never placed on the stump 20 mm low nor on the coronoid 30 mm in
// front (on openkbp-train folds 1-4 that put Co 25-32 mm from the clinical
// contour's in 6 of 90 patients).
TEST(Landmarks, ALostCondyleLeavesTheCoronoidAsCrNotCo) {
  for (double below : {20.0, 30.0}) {
    const LostCondyle c = landmarks_without_left_condyle(below);
    const auto& r = c.r;
    EXPECT_FALSE(r.landmarks.has("Co_L")) << below;
    ASSERT_TRUE(r.why_missing.count("Co_L")) << below;
    EXPECT_NE(r.why_missing.at("Co_L").find("condyle is not on the segmented surface"), std::string::npos)
        << r.why_missing.at("Co_L");
    ASSERT_TRUE(r.landmarks.has("Cr_L")) << below;
    EXPECT_LE(ms::norm(*r.landmarks.find("Cr_L") - c.cr), 1.5) << below;
    // The right side keeps both processes where they are.
    ASSERT_TRUE(r.landmarks.has("Co_R") && r.landmarks.has("Cr_R")) << below;
    EXPECT_LE(ms::norm(*r.landmarks.find("Co_R") - c.co_r), 1.5) << below;
    EXPECT_LE(ms::norm(*r.landmarks.find("Cr_R") - c.cr_r), 1.5) << below;
    std::printf("condylar process removed %.0f mm below the tips: Co_L missing (%s)\n", below,
                r.why_missing.at("Co_L").substr(0, 120).c_str());
  }
}

// A head 30 mm off centre: the scan's side cuts the left condyle, coronoid and
// angle (their true points lie outside it). A landmark whose neighbourhood
// reaches the cut is missing too — the gonion found 2 mm inside the cut was the
// middle of what was left of the angle, 2.7 mm off — and the other side's are
// where they belong.
TEST(Landmarks, LandmarksNearALateralCutAreMissing) {
  const CutScan c = landmarks_on_cut_scan({150, 150, 140}, {30, 0, 0});
  const auto& r = c.r;
  for (const char* n : {"Co_L", "Cr_L", "Go_L"}) {
    EXPECT_FALSE(r.landmarks.has(n)) << n;
    // Never silently missing: each says why (docs/landmarks.md, "Missing landmarks").
    ASSERT_TRUE(r.why_missing.count(n)) << n;
    EXPECT_NE(r.why_missing.at(n).find("edge of the scan"), std::string::npos) << r.why_missing.at(n);
  }
  for (const auto& n : r.missing) EXPECT_TRUE(r.why_missing.count(n)) << n;
  for (const auto& [n, why] : r.why_missing) EXPECT_FALSE(r.landmarks.has(n)) << n << ": " << why;
  for (const char* n : {"Co_R", "Cr_R", "Go_R", "Me", "Pog"}) {
    ASSERT_TRUE(r.landmarks.has(n)) << n;
    EXPECT_LE(ms::norm(*r.landmarks.find(n) - *c.ph.landmarks.find(n)), 1.5) << n;
  }
  // Where the scan cuts the mandible, in the head's frame: the head moved 30 mm to its left.
  EXPECT_EQ(r.cut_at, std::vector<std::string>{"left side"});
}

}  // namespace

// Head frame order (docs/landmarks.md): the palatal plane when it agrees with
// the atlas's superior axis within 40 degrees; the atlas's axis when it does
// not (a nasal floor found on the wrong structure); the scan's axes without
// either. Checked against the phantom's known head frame.
TEST(HeadFrame, PalatalPlaneUnlessTheAtlasAxisRejectsIt) {
  ms::phantom::PhantomParams p;
  p.spacing = {1, 1, 1};
  p.fov_mm = {150, 140, 130};
  p.pitch_deg = 10;
  p.occlusal_gap_mm = 2;
  p.noise_hu = 0;
  const auto ph = ms::phantom::generate(p);
  const auto surf = ms::surface::mesh_from_mask(ph.mandible);
  auto angle = [](const Vec3& a, const Vec3& b) { return std::acos(std::min(1.0, ms::dot(a, b))) * 180 / M_PI; };
  ms::landmarks::PalateOptions po;
  ms::landmarks::PalatalPlane palate;
  ms::landmarks::HeadFrame frame;
  // The atlas agrees (its axis 10 degrees from the head's): the palatal plane is used.
  const Vec3 near = ms::normalized(Vec3{ph.superior[0], ph.superior[1] + 0.18, ph.superior[2]});
  po.atlas_superior = near;
  ms::landmarks::detect_in_head_frame(ph.ct, surf.mesh, {}, po, &palate, &frame);
  EXPECT_EQ(frame.source, "palatal");
  EXPECT_LT(angle(frame.superior, ph.superior), 1.0);
  // The atlas's axis 60 degrees away: the palatal line is rejected, the atlas's axis used.
  const Vec3 far = ms::normalized(Vec3{ph.superior[0], ph.superior[1] + 1.73, ph.superior[2]});
  po.atlas_superior = far;
  ms::landmarks::detect_in_head_frame(ph.ct, surf.mesh, {}, po, &palate, &frame);
  EXPECT_EQ(frame.source, "mandible");
  EXPECT_FALSE(palate.found);
  EXPECT_NE(palate.reason.find("degrees"), std::string::npos) << palate.reason;
  EXPECT_LT(angle(frame.superior, far), 1e-6);
  // Without the atlas: the palatal plane again.
  po.atlas_superior.reset();
  ms::landmarks::detect_in_head_frame(ph.ct, surf.mesh, {}, po, &palate, &frame);
  EXPECT_EQ(frame.source, "palatal");
}
