#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <set>

#include "reports/interpretation.h"

using namespace ms::reports;

namespace {

const Interpretation& find(const std::vector<Interpretation>& all, const std::string& key) {
  for (const auto& x : all)
    if (x.key == key) return x;
  ADD_FAILURE() << "no interpretation " << key;
  static Interpretation none;
  return none;
}

}  // namespace

TEST(Interpretation, ClassifyUsesHalfOpenBands) {
  const Thresholds t{2.0, 4.0};
  EXPECT_EQ(classify(0.0, t), Band::Typical);
  EXPECT_EQ(classify(1.999, t), Band::Typical);
  EXPECT_EQ(classify(2.0, t), Band::Mild);
  EXPECT_EQ(classify(3.999, t), Band::Mild);
  EXPECT_EQ(classify(4.0, t), Band::Marked);
  EXPECT_EQ(classify(40.0, t), Band::Marked);
  EXPECT_EQ(classify(kNaN, t), Band::Unavailable);
  EXPECT_EQ(classify(INFINITY, t), Band::Unavailable);
}

TEST(Interpretation, HabetsIndex) {
  EXPECT_NEAR(habets_index_pct(55.0, 50.0), 100.0 * 5.0 / 105.0, 1e-12);
  EXPECT_NEAR(habets_index_pct(50.0, 55.0), 100.0 * 5.0 / 105.0, 1e-12);  // side does not matter
  EXPECT_DOUBLE_EQ(habets_index_pct(60.0, 60.0), 0.0);
  EXPECT_TRUE(std::isnan(habets_index_pct(kNaN, 60.0)));
  EXPECT_TRUE(std::isnan(habets_index_pct(0.0, 0.0)));
}

// The phantom numbers of docs/method.md that the SAF band is derived from:
// every symmetric phantom typical, every +4 mm ramus / +2 mm body / +2 mm
// chin phantom marked, and the +2 mm ramus phantoms typical or mild.
TEST(Interpretation, SafBandsReproduceThePhantomTable) {
  for (double v : {0.0038, 0.0090, 0.0147, 0.0102}) EXPECT_EQ(classify(v, kSafThresholds), Band::Typical) << v;
  for (double v : {0.0218, 0.0246, 0.0281, 0.0295, 0.0257, 0.0291, 0.0262, 0.0241, 0.0486})
    EXPECT_EQ(classify(v, kSafThresholds), Band::Marked) << v;
  for (double v : {0.0161, 0.0204, 0.0165}) EXPECT_EQ(classify(v, kSafThresholds), Band::Mild) << v;
  EXPECT_EQ(classify(0.0113, kSafThresholds), Band::Typical);  // the overlap docs/method.md reports
}

TEST(Interpretation, HeadlineNumbersAreBanded) {
  InterpretationInputs in;
  in.saf_score = 0.022;
  in.mirror_rms_mm = 0.53;
  in.mirror_p95_mm = 2.5;
  in.ramus_L_mm = 63.9;
  in.ramus_R_mm = 56.0;  // index 6.6 %
  in.menton_to_plane_mm = -4.3;  // 4.3 mm towards the right
  in.gonial_L_deg = 117.0;
  in.gonial_R_deg = 121.5;
  in.body_L_mm = 84.1;
  in.body_R_mm = 84.2;
  const auto all = interpret(in);
  ASSERT_EQ(all.size(), 6u);

  const auto& saf = find(all, "saf_score");
  EXPECT_EQ(saf.band, Band::Marked);
  EXPECT_TRUE(saf.provisional);
  EXPECT_NE(saf.thresholds.find("phantom-derived, not clinically validated"), std::string::npos);

  const auto& mirror = find(all, "mirror_distance");
  EXPECT_EQ(mirror.band, Band::Mild);
  EXPECT_DOUBLE_EQ(mirror.banded_value, 2.5);
  EXPECT_EQ(mirror.value_text, "0.53 / 2.50 mm");

  const auto& ramus = find(all, "ramus_height");
  EXPECT_EQ(ramus.band, Band::Marked);
  EXPECT_NEAR(ramus.banded_value, 100.0 * 7.9 / 119.9, 1e-9);
  EXPECT_EQ(ramus.value_text, "+7.90 mm");
  EXPECT_FALSE(ramus.provisional);

  const auto& me = find(all, "menton_deviation");
  EXPECT_EQ(me.band, Band::Marked);
  EXPECT_DOUBLE_EQ(me.banded_value, 4.3);
  EXPECT_NE(me.detail.find("towards the right"), std::string::npos);

  const auto& gonial = find(all, "gonial_angle");
  EXPECT_EQ(gonial.band, Band::Unbanded);
  EXPECT_EQ(gonial.value_text, "-4.5\xC2\xB0");
  EXPECT_EQ(find(all, "body_length").band, Band::Unbanded);
}

TEST(Interpretation, MissingNumbersAreUnavailableNotTypical) {
  const auto all = interpret(InterpretationInputs{});
  for (const auto& x : all) {
    EXPECT_EQ(x.band, Band::Unavailable) << x.key;
    EXPECT_NE(x.value_text.find("n/a"), std::string::npos) << x.key;
  }
}

TEST(Interpretation, EveryCitedSourceIsListedOnceAndEveryBandSaysWhereItComesFrom) {
  std::set<std::string> ids;
  for (const auto& r : interpretation_references()) {
    EXPECT_TRUE(ids.insert(r.id).second) << "duplicate " << r.id;
    EXPECT_FALSE(r.citation.empty());
  }
  for (const auto& x : interpret(InterpretationInputs{})) {
    EXPECT_FALSE(x.meaning.empty()) << x.key;
    EXPECT_FALSE(x.thresholds.empty()) << x.key;
    for (const auto& s : x.sources) EXPECT_TRUE(ids.count(s)) << x.key << " cites unknown " << s;
    if (x.key == "saf_score" || x.key == "mirror_distance" || x.key == "ramus_height" || x.key == "menton_deviation")
      EXPECT_FALSE(x.sources.empty()) << x.key;
  }
}

TEST(Interpretation, InputsFromARun) {
  RunSummary s;
  s.saf.score = 0.012;
  s.mirror.per_vertex = {0.1, -0.2};
  s.mirror.overall.rms = 0.3;
  s.mirror.overall.p95 = 0.9;
  s.bilateral["ramus_height_mm"] = {60.0, 58.0, 2.0, 60.0 / 58.0};
  s.bilateral["gonial_angle_deg"] = {120.0, 118.0, 2.0, 120.0 / 118.0};
  s.landmarks.landmarks.points = {{"Me", {3.0, -40.0, -30.0}}};
  s.reference.plane.point = {1.0, 0.0, 0.0};
  s.reference.plane.normal = {1.0, 0.0, 0.0};  // towards the patient's left
  const auto in = interpretation_inputs(s);
  EXPECT_DOUBLE_EQ(in.saf_score, 0.012);
  EXPECT_DOUBLE_EQ(in.mirror_p95_mm, 0.9);
  EXPECT_DOUBLE_EQ(in.ramus_L_mm, 60.0);
  EXPECT_DOUBLE_EQ(in.ramus_R_mm, 58.0);
  EXPECT_DOUBLE_EQ(in.gonial_R_deg, 118.0);
  EXPECT_DOUBLE_EQ(in.menton_to_plane_mm, 2.0);
  EXPECT_TRUE(std::isnan(in.body_L_mm));  // not measured

  EXPECT_FALSE(in.menton_plane_cranial);
  // With a cranial mid-sagittal plane, menton is measured from it.
  s.cranial.found = true;
  s.cranial.plane.point = {-2.0, 0.0, 0.0};
  s.cranial.plane.normal = {1.0, 0.0, 0.0};
  const auto inc = interpretation_inputs(s);
  EXPECT_TRUE(inc.menton_plane_cranial);
  EXPECT_DOUBLE_EQ(inc.menton_to_plane_mm, 5.0);
  EXPECT_DOUBLE_EQ(inc.menton_to_mandible_plane_mm, 2.0);
  const auto cards = interpret(inc);
  const auto& me = *std::find_if(cards.begin(), cards.end(), [](const auto& x) { return x.key == "menton_deviation"; });
  EXPECT_EQ(me.band, Band::Marked);  // 5 mm against the skull, though 2 mm against the mandible's own plane
  EXPECT_NE(me.title.find("cranial"), std::string::npos);
  EXPECT_EQ(me.measured_from, "cranial_plane");
  const auto own = interpret(in);
  const auto& me_own = *std::find_if(own.begin(), own.end(), [](const auto& x) { return x.key == "menton_deviation"; });
  EXPECT_EQ(me_own.measured_from, "mandible_plane");
  for (const auto& x : own)
    if (x.key != "menton_deviation") EXPECT_TRUE(x.measured_from.empty()) << x.key;

  RunSummary empty;
  empty.saf.score = -1;  // not computed
  const auto none = interpretation_inputs(empty);
  EXPECT_TRUE(std::isnan(none.saf_score));
  EXPECT_TRUE(std::isnan(none.mirror_rms_mm));
  EXPECT_TRUE(std::isnan(none.menton_to_plane_mm));
}
