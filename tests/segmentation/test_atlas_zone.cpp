// atlas_zone_mask (docs/segmentation.md, "the atlas's zone"): the zone's bone,
// and the bone beyond it that is attached to it and to nothing outside the
// training mandibles' support.
#include <gtest/gtest.h>

#include "segmentation/atlas_zone.h"

using ms::segmentation::atlas_zone_mask;
using ms::segmentation::kAtlasSupportP;
using ms::segmentation::kAtlasZoneP;

namespace {

struct Grid {
  std::array<std::size_t, 3> dims{40, 10, 10};
  std::vector<std::uint8_t> bone = std::vector<std::uint8_t>(4000, 0);
  std::vector<float> p = std::vector<float>(4000, 0.0f);
  std::size_t at(std::size_t x, std::size_t y, std::size_t z) const { return x + dims[0] * (y + dims[1] * z); }
  // A bar of bone along x from x0 to x1 (inclusive) at (y, z) = (5, 5), with probability p.
  void bar(std::size_t x0, std::size_t x1, float prob) {
    for (std::size_t x = x0; x <= x1; ++x) bone[at(x, 5, 5)] = 1, p[at(x, 5, 5)] = prob;
  }
};

}  // namespace

TEST(AtlasZone, TakesTheZonesBoneAndAFreeAppendix) {
  Grid g;
  g.bar(0, 9, 0.6f);                                  // the zone
  g.bar(10, 14, static_cast<float>(kAtlasZoneP / 2));  // a longer process, within the support: joins
  const auto m = atlas_zone_mask(g.bone, g.p, g.dims);
  for (std::size_t x = 0; x <= 14; ++x) EXPECT_EQ(m[g.at(x, 5, 5)], 1) << x;
  EXPECT_EQ(m[g.at(20, 5, 5)], 0);
}

TEST(AtlasZone, LeavesBoneFusedToTheZoneThatReachesBeyondTheSupport) {
  Grid g;
  g.bar(0, 9, 0.6f);
  g.bar(10, 14, static_cast<float>(kAtlasZoneP / 2));
  g.bar(15, 30, static_cast<float>(kAtlasSupportP / 2));  // the skull base beyond the training mandibles
  const auto m = atlas_zone_mask(g.bone, g.p, g.dims);
  for (std::size_t x = 0; x <= 9; ++x) EXPECT_EQ(m[g.at(x, 5, 5)], 1) << x;
  for (std::size_t x = 10; x <= 30; ++x) EXPECT_EQ(m[g.at(x, 5, 5)], 0) << x;
}

TEST(AtlasZone, LeavesBoneThatDoesNotTouchTheZone) {
  Grid g;
  g.bar(0, 9, 0.6f);
  g.bar(12, 16, static_cast<float>(kAtlasZoneP / 2));  // two voxels away: a separate bone (the hyoid)
  const auto m = atlas_zone_mask(g.bone, g.p, g.dims);
  for (std::size_t x = 12; x <= 16; ++x) EXPECT_EQ(m[g.at(x, 5, 5)], 0) << x;
  EXPECT_EQ(m[g.at(9, 5, 5)], 1);
}
