// Segmentation: external label maps (resampling, validation) and the
// automatic segmentation measured against phantom ground truth.
#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"
#include "phantom/phantom.h"
#include "segmentation/segmentation.h"

using namespace ms;

namespace {

Geometry grid(std::array<std::size_t, 3> size, Vec3 spacing, Vec3 origin, double angle = 0) {
  Geometry g;
  g.size = size;
  g.spacing = spacing;
  g.origin = origin;
  const double c = std::cos(angle), s = std::sin(angle);
  g.direction = {c, -s, 0, s, c, 0, 0, 0, 1};
  return g;
}

// Label 1: sphere r=12 at (5,-3,2); label 2: box elsewhere.
LabelMap analytic_labels(const Geometry& g) {
  LabelMap m;
  m.geom = g;
  m.labels.assign(g.voxel_count(), 0);
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        const Vec3 p = g.index_to_lps(i, j, k);
        if (distance(p, Vec3{5, -3, 2}) < 12) m.labels[g.linear(i, j, k)] = 1;
        else if (std::abs(p[0] + 18) < 5 && std::abs(p[1]) < 5 && std::abs(p[2]) < 5) m.labels[g.linear(i, j, k)] = 2;
      }
  return m;
}

double dice(const Mask& a, const Mask& b) {
  std::size_t inter = 0, na = 0, nb = 0;
  for (std::size_t i = 0; i < a.data.size(); ++i) {
    na += a.data[i];
    nb += b.data[i];
    inter += a.data[i] && b.data[i];
  }
  return 2.0 * inter / static_cast<double>(na + nb);
}

Mask sphere_on(const Geometry& g) {
  Mask m;
  m.geom = g;
  m.data.assign(g.voxel_count(), 0);
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) m.data[g.linear(i, j, k)] = distance(g.index_to_lps(i, j, k), Vec3{5, -3, 2}) < 12;
  return m;
}

}  // namespace

TEST(ExternalMask, SameGridIsTakenAsIs) {
  const Geometry ct = grid({48, 40, 36}, {0.8, 0.8, 1.0}, {-20, -16, -17});
  const auto r = segmentation::from_label_map(ct, analytic_labels(ct), 1, "m.nii.gz");
  EXPECT_EQ(r.method, "external");
  EXPECT_EQ(r.mask.data, sphere_on(ct).data);
  EXPECT_TRUE(r.warnings.empty());
  EXPECT_FALSE(r.truncated);
}

TEST(ExternalMask, OtherGridIsResampledInLpsSpace) {
  const Geometry ct = grid({48, 40, 36}, {0.8, 0.8, 1.0}, {-20, -16, -17});
  // Coarser, shifted and rotated 20 degrees about S.
  const Geometry other = grid({36, 36, 30}, {1.3, 1.3, 1.4}, {-22, -25, -20}, 0.35);
  const auto r = segmentation::from_label_map(ct, analytic_labels(other), 1, "m.nii.gz");
  EXPECT_GT(dice(r.mask, sphere_on(ct)), 0.93);
  ASSERT_FALSE(r.warnings.empty());
  EXPECT_NE(r.warnings[0].find("resampled"), std::string::npos);
}

TEST(ExternalMask, ValidatesLabelsAndOverlap) {
  const Geometry ct = grid({48, 40, 36}, {0.8, 0.8, 1.0}, {-20, -16, -17});
  const LabelMap lm = analytic_labels(ct);
  auto code = [&](const LabelMap& m, int label) {
    try {
      segmentation::from_label_map(ct, m, label, "m.nii.gz");
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("m.nii.gz"), std::string::npos);
      return e.code();
    }
    return ExitCode::Ok;
  };
  EXPECT_EQ(code(lm, -1), ExitCode::Usage);       // two labels, none chosen
  EXPECT_EQ(code(lm, 7), ExitCode::NoMandible);   // label absent
  LabelMap empty = lm;
  std::fill(empty.labels.begin(), empty.labels.end(), 0);
  EXPECT_EQ(code(empty, 1), ExitCode::NoMandible);
  LabelMap far = analytic_labels(grid({20, 20, 20}, {1, 1, 1}, {500, 500, 500}));
  far.labels[0] = 1;
  EXPECT_EQ(code(far, 1), ExitCode::InputInvalid);  // no overlap
  EXPECT_EQ(code(lm, 2), ExitCode::Ok);
}

TEST(ExternalMask, SeveralPartsAndTruncationAreReported) {
  const Geometry ct = grid({30, 30, 30}, {1, 1, 1}, {0, 0, 0});
  LabelMap m;
  m.geom = ct;
  m.labels.assign(ct.voxel_count(), 0);
  m.labels[ct.linear(5, 5, 5)] = 1;
  m.labels[ct.linear(20, 20, 20)] = 1;
  m.labels[ct.linear(0, 10, 10)] = 1;  // on the border
  const auto r = segmentation::from_label_map(ct, m, 1, "m.nii.gz");
  EXPECT_TRUE(r.truncated);
  bool parts = false;
  for (const auto& w : r.warnings) parts |= w.find("3 separate parts") != std::string::npos;
  EXPECT_TRUE(parts);
}
