// Quality control (docs/qc.md): which summaries pass, warn and fail.
#include <gtest/gtest.h>

#include <cmath>

#include "reports/qc.h"
#include "reports/run_summary.h"

using namespace ms;
using namespace ms::reports;

namespace {

// An adult mandible found where the atlas puts it: 8 landmarks, condyles
// 100 mm apart and 60 mm above menton, 65 cm3, upright fit 0.80 vs 0.50.
RunSummary good_run() {
  RunSummary s;
  s.segmentation_method = "auto";
  s.seg_volume_mm3 = 65000;
  s.atlas.found = true;
  s.atlas.ncc = 0.80;
  s.atlas.mirrored_ncc = 0.50;
  s.atlas_agreement = 0.55;
  const std::pair<const char*, Vec3> pts[] = {{"Co_L", {50, 10, 60}}, {"Co_R", {-50, 10, 60}}, {"Cr_L", {45, -10, 55}},
                                              {"Cr_R", {-45, -10, 55}}, {"Go_L", {48, 15, 5}}, {"Go_R", {-48, 15, 5}},
                                              {"Me", {0, -70, 0}}, {"Pog", {0, -75, 10}}};
  for (const auto& [n, p] : pts) s.landmarks.landmarks.set(n, p);
  return s;
}

const QcCheck* check(const Qc& q, const std::string& name) {
  for (const QcCheck& c : q.checks)
    if (c.name == name) return &c;
  return nullptr;
}

}  // namespace

TEST(Qc, AnAdultMandibleWhereTheAtlasPutsItPasses) {
  const Qc q = evaluate_qc(good_run());
  EXPECT_EQ(q.status, "pass");
  EXPECT_TRUE(q.failed().empty());
}

TEST(Qc, AHeadUpsideDownFailsOnTheOrientationAndTheMenton) {
  RunSummary s = good_run();
  s.atlas.ncc = 0.50, s.atlas.mirrored_ncc = 0.74;
  for (const char* n : {"Me", "Pog"}) s.landmarks.landmarks.set(n, {0, -70, 90});  // menton 30 mm above the condyles
  const Qc q = evaluate_qc(s);
  EXPECT_EQ(q.status, "fail");
  EXPECT_FALSE(check(q, "orientation_margin")->passed);
  EXPECT_FALSE(check(q, "condyles_above_menton_mm")->passed);
}

TEST(Qc, AnotherBoneFailsOnTheVolumeAndALowAgreementWarns) {
  RunSummary s = good_run();
  s.atlas_agreement = 0.05;
  s.seg_volume_mm3 = 199000;  // the Visible Human's skull vault
  const Qc q = evaluate_qc(s);
  EXPECT_EQ(q.status, "fail");
  EXPECT_FALSE(check(q, "atlas_agreement")->passed);
  EXPECT_FALSE(check(q, "atlas_agreement")->fatal) << "the mask lies within the atlas's zone: agreement only warns";
  EXPECT_FALSE(check(q, "mandible_volume_cm3")->passed);
  s.seg_volume_mm3 = 30000;  // a small mandible: only the agreement is low
  EXPECT_EQ(evaluate_qc(s).status, "warn");
}

// A small field of view (the 150 mm phantoms): no upright placement fits in
// the scan, so neither the orientation nor the agreement can be measured;
// the unfitted atlas only warns.
TEST(Qc, AnAtlasThatDoesNotFitTheScanOnlyWarns) {
  RunSummary s = good_run();
  s.atlas.found = false;
  s.atlas.ncc = -1;
  s.atlas.mirrored_ncc = 0.43;
  s.atlas_agreement = -1;
  const Qc q = evaluate_qc(s);
  EXPECT_EQ(q.status, "warn");
  EXPECT_TRUE(check(q, "orientation_margin")->passed);
  EXPECT_TRUE(std::isnan(check(q, "orientation_margin")->value));
  EXPECT_TRUE(check(q, "atlas_agreement")->passed);
  EXPECT_FALSE(check(q, "atlas_fit_ncc")->passed);
}

TEST(Qc, MissingLandmarksAndTruncationWarn) {
  RunSummary s = good_run();
  s.landmarks.landmarks.points.erase(s.landmarks.landmarks.points.begin() + 2);  // Cr_L
  s.truncated = true;
  const Qc q = evaluate_qc(s);
  EXPECT_EQ(q.status, "warn");
  EXPECT_EQ(check(q, "landmarks_missing")->value, 1.0);
}
