// The palatal plane (landmarks/palate.h): the head's superior direction from
// the nasal floor, which corrects head pitch in the landmark frame. Checked
// against the phantom's head frame on scans unlike the landmark matrix's
// (noise, blur, metal streaks, teeth in occlusion, thick slices), and a scan
// that ends below the palate must say it has none rather than guess.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "landmarks/landmarks.h"
#include "landmarks/palate.h"
#include "phantom/phantom.h"
#include "surface/surface.h"

namespace {

struct Scan {
  const char* name;
  ms::Vec3 spacing;
  double yaw, pitch, roll;
  double noise, blur;
  bool metal;
  double gap;
};

std::ostream& operator<<(std::ostream& o, const Scan& s) { return o << s.name; }

class PalatalPlane : public ::testing::TestWithParam<Scan> {};

TEST_P(PalatalPlane, GivesTheHeadsSuperiorWithinOneDegree) {
  const Scan& s = GetParam();
  ms::phantom::PhantomParams p;
  p.spacing = s.spacing;
  p.fov_mm = {150, 140, 130};
  p.yaw_deg = s.yaw, p.pitch_deg = s.pitch, p.roll_deg = s.roll;
  p.noise_hu = s.noise, p.blur_mm = s.blur;
  p.metal = s.metal;
  p.occlusal_gap_mm = s.gap;
  const auto ph = ms::phantom::generate(p);
  const auto surf = ms::surface::mesh_from_mask(ph.mandible);
  const auto plane = ms::landmarks::mandible_plane(surf.mesh);
  const auto r = ms::landmarks::find_palatal_plane(ph.ct, surf.mesh, plane);
  ASSERT_TRUE(r.found) << r.reason;
  const double err = std::acos(std::min(1.0, ms::dot(r.superior, ph.superior))) * 180 / M_PI;
  std::printf("%s: tilt %.2f deg, superior %.2f deg from the head's, %zu samples over %.0f mm, rms %.2f mm\n", s.name, r.tilt_deg, err,
              r.samples, r.length_mm, r.rms_mm);
  EXPECT_LT(err, 1.0);
  // The support spans most of the floor (the phantom's nasal cavity is 52 mm
  // long), not a short stretch that happens to agree.
  EXPECT_GT(r.length_mm, 30.0);
}

INSTANTIATE_TEST_SUITE_P(
    Phantoms, PalatalPlane,
    ::testing::Values(Scan{"noisy_occlusion_metal_0_8mm", {0.8, 0.8, 0.8}, 6, -15, -4, 40, 0.6, true, 0},
                      Scan{"chin_down_18", {1, 1, 1}, -5, 18, 7, 15, 0.4, false, 1},
                      Scan{"thick_slices_0_5x3mm", {0.5, 0.5, 3.0}, 0, 12, 0, 20, 0.4, false, 1}),
    [](const ::testing::TestParamInfo<Scan>& i) { return std::string(i.param.name); });

// A scan of the lower face whose top edge passes below the palate: reported
// not found with a reason, never a line through something else.
TEST(PalatalPlaneMissing, ScanEndingBelowThePalateHasNone) {
  ms::phantom::PhantomParams p;
  p.spacing = {1, 1, 1};
  p.fov_mm = {150, 140, 100};
  p.shift_mm = {0, 0, 35};  // the head moved up: the grid ends ~10 mm below the nasal floor
  const auto ph = ms::phantom::generate(p);
  const auto surf = ms::surface::mesh_from_mask(ph.mandible);
  const auto r = ms::landmarks::find_palatal_plane(ph.ct, surf.mesh, ms::landmarks::mandible_plane(surf.mesh));
  EXPECT_FALSE(r.found) << "tilt " << r.tilt_deg << ", " << r.samples << " samples over " << r.length_mm << " mm";
  EXPECT_FALSE(r.reason.empty());
  std::printf("reason: %s\n", r.reason.c_str());
}

}  // namespace
