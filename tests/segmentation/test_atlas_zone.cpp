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
  std::array<std::array<std::size_t, 2>, 3> faces() const { return {{{0, dims[0] - 1}, {0, dims[1] - 1}, {0, dims[2] - 1}}}; }
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

// The zone's rim (add_zone_rim): a zone cut 2 mm inside a bone's edge over
// its length, that bone fused at one end to a skull beyond the training
// mandibles' support (no free appendix): the rim is added, the skull is not,
// nor the rim's voxels that lead out to it or to the grid's face.
TEST(AtlasZone, AddsTheRimOfABoneTheZoneCutsThroughButNotTheBoneItIsFusedTo) {
  using ms::segmentation::add_zone_rim;
  Grid g;
  const float rim_p = static_cast<float>(kAtlasZoneP / 2);
  for (std::size_t x = 0; x <= 20; ++x) {
    g.bone[g.at(x, 5, 5)] = 1, g.p[g.at(x, 5, 5)] = 0.6f;   // the zone
    g.bone[g.at(x, 6, 5)] = 1, g.p[g.at(x, 6, 5)] = rim_p;  // the cortex beyond it, ending in soft tissue at y 8
    g.bone[g.at(x, 7, 5)] = 1, g.p[g.at(x, 7, 5)] = rim_p;
  }
  for (std::size_t x = 21; x < 40; ++x) g.bone[g.at(x, 7, 5)] = 1, g.p[g.at(x, 7, 5)] = static_cast<float>(kAtlasSupportP / 2);
  const auto zone = atlas_zone_mask(g.bone, g.p, g.dims);
  EXPECT_EQ(zone[g.at(10, 6, 5)], 0) << "fused to the skull: no free appendix";
  const auto m = add_zone_rim(zone, g.bone, g.bone, g.p, g.dims, {1.0, 1.0, 1.0}, g.faces());
  for (std::size_t x = 2; x <= 17; ++x) EXPECT_EQ(m[g.at(x, 6, 5)] + m[g.at(x, 7, 5)], 2) << x;
  EXPECT_EQ(m[g.at(0, 7, 5)], 0) << "on the grid's face: it may go on outside";
  for (std::size_t x = 21; x < 40; ++x) EXPECT_EQ(m[g.at(x, 7, 5)], 0) << x;
  EXPECT_EQ(m[g.at(20, 7, 5)], 0) << "leads out to the skull";
}

// Bone beside the zone that goes on beyond the rim's reach (kZoneRimMm plus
// a voxel) within the support and then into a skull (a fossa's roof over a
// condyle): not added, not even its voxels touching the zone.
TEST(AtlasZone, LeavesBoneThatGoesOnBeyondTheRim) {
  using ms::segmentation::add_zone_rim;
  using ms::segmentation::kZoneRimMm;
  Grid g;
  g.bar(0, 9, 0.6f);
  const float in_support = static_cast<float>(kAtlasZoneP / 2);
  for (std::size_t y = 6; y < 10; ++y) g.bone[g.at(5, y, 5)] = 1, g.p[g.at(5, y, 5)] = in_support;  // up from the zone
  for (std::size_t x = 5; x < 40; ++x)  // and on, far beyond, into the skull
    g.bone[g.at(x, 9, 5)] = 1, g.p[g.at(x, 9, 5)] = x < 30 ? in_support : static_cast<float>(kAtlasSupportP / 2);
  ASSERT_LT(kZoneRimMm + 1.0, 20.0);
  const auto m = add_zone_rim(atlas_zone_mask(g.bone, g.p, g.dims), g.bone, g.bone, g.p, g.dims, {1.0, 1.0, 1.0}, g.faces());
  for (std::size_t y = 6; y < 10; ++y) EXPECT_EQ(m[g.at(5, y, 5)], 0) << y;
  for (std::size_t x = 0; x <= 9; ++x) EXPECT_EQ(m[g.at(x, 5, 5)], 1) << x;
}

// A fragment the bone threshold cut from its bone (an upper tooth's crown
// whose root runs on in alveolar bone blurred below the threshold) does not
// end in soft tissue: it goes on through what is not soft tissue and is not
// added; with soft tissue beyond it, the same fragment is the rim.
TEST(AtlasZone, AFragmentThatGoesOnBelowTheBoneThresholdIsNoRim) {
  using ms::segmentation::add_zone_rim;
  Grid g;
  g.bar(0, 9, 0.6f);
  const float rim_p = static_cast<float>(kAtlasZoneP / 2);
  for (std::size_t x = 2; x <= 4; ++x) g.bone[g.at(x, 6, 5)] = 1, g.p[g.at(x, 6, 5)] = rim_p;  // the fragment
  std::vector<std::uint8_t> not_soft = g.bone;
  for (std::size_t y = 7; y < 10; ++y)  // blurred bone above it, going on into the maxilla beyond the support
    for (std::size_t z = 5; z < 10; ++z) not_soft[g.at(3, y, z)] = 1, g.p[g.at(3, y, z)] = z < 9 ? rim_p : static_cast<float>(kAtlasSupportP / 2);
  std::vector<std::uint8_t> zone(g.bone.size(), 0);  // the zone alone (standing free, the fragment is an appendix)
  for (std::size_t x = 0; x <= 9; ++x) zone[g.at(x, 5, 5)] = 1;
  const auto with_blur = add_zone_rim(zone, g.bone, not_soft, g.p, g.dims, {1.0, 1.0, 1.0}, g.faces());
  EXPECT_EQ(with_blur[g.at(3, 6, 5)], 0);
  const auto with_soft_tissue = add_zone_rim(zone, g.bone, g.bone, g.p, g.dims, {1.0, 1.0, 1.0}, g.faces());
  for (std::size_t x = 2; x <= 4; ++x) EXPECT_EQ(with_soft_tissue[g.at(x, 6, 5)], 1) << x;
}

// Processes past the support (atlas_zone_mask's in_room): a coronoid tip
// reaching beyond every training mandible joins when all of it lies in the
// room a taller process may take (the grown support above the sigmoid
// notch); with one voxel outside that room (below the notch, or past the
// grown support: an upper crown, a piece of the arch) it does not, nor
// without a room.
TEST(AtlasZone, TakesAProcessPastTheSupportOnlyWithinItsRoom) {
  Grid g;
  g.bar(0, 9, 0.6f);                                      // the zone
  g.bar(10, 12, static_cast<float>(kAtlasZoneP / 2));     // within the support
  g.bar(13, 15, static_cast<float>(kAtlasSupportP / 2));  // past it
  std::vector<std::uint8_t> room(g.bone.size(), 0);
  for (std::size_t x = 10; x <= 15; ++x) room[g.at(x, 5, 5)] = 1;
  const auto in_room = [&](std::size_t i) { return room[i] != 0; };
  const auto m = atlas_zone_mask(g.bone, g.p, g.dims, in_room);
  for (std::size_t x = 0; x <= 15; ++x) EXPECT_EQ(m[g.at(x, 5, 5)], 1) << x;
  const auto without = atlas_zone_mask(g.bone, g.p, g.dims);
  for (std::size_t x = 10; x <= 15; ++x) EXPECT_EQ(without[g.at(x, 5, 5)], 0) << x;
  room[g.at(15, 5, 5)] = 0;
  const auto left = atlas_zone_mask(g.bone, g.p, g.dims, in_room);
  for (std::size_t x = 10; x <= 15; ++x) EXPECT_EQ(left[g.at(x, 5, 5)], 0) << x;
  // A piece past the support that does not touch the zone stays out.
  Grid h;
  h.bar(0, 9, 0.6f);
  h.bar(12, 15, static_cast<float>(kAtlasSupportP / 2));
  const auto apart = atlas_zone_mask(h.bone, h.p, h.dims, [](std::size_t) { return true; });
  for (std::size_t x = 12; x <= 15; ++x) EXPECT_EQ(apart[h.at(x, 5, 5)], 0) << x;
}

// The superior joint space along the vertical (extend_to_joint_space): a
// column through a condyle the zone cut short, the bone above its edge, a
// gap and the fossa's roof. At 1.5 mm slices kZoneRimMm (5 mm) is 3 voxels of
// bone and kJointGapMaxMm (5 mm) 3 voxels of gap.
namespace {

struct Column {
  std::array<std::size_t, 3> dims{3, 3, 24};
  std::vector<std::uint8_t> mask = std::vector<std::uint8_t>(3 * 3 * 24, 0);
  std::vector<std::uint8_t> bone = std::vector<std::uint8_t>(3 * 3 * 24, 0);
  std::size_t at(std::size_t z) const { return 1 + 3 * (1 + 3 * z); }  // the middle column
  // mask below `edge`, bone from `edge` up to `gap` (exclusive), non-bone for
  // `gap_voxels`, then bone (the roof) to the top unless roof is false.
  Column(std::size_t edge, std::size_t gap, std::size_t gap_voxels, bool roof = true) {
    for (std::size_t z = 0; z < dims[2]; ++z) {
      const bool in_gap = z >= gap && z < gap + gap_voxels;
      bone[at(z)] = z < gap || (!in_gap && roof);
      mask[at(z)] = z < edge;
    }
  }
  std::vector<std::uint8_t> extended(const std::function<bool(std::size_t)>& room = [](std::size_t) { return true; }) const {
    return ms::segmentation::extend_to_joint_space(mask, bone, dims, 2, +1, 1.5, room);
  }
};

}  // namespace

TEST(AtlasZone, TakesTheCondylesTopUpToTheJointSpace) {
  const Column c(/*edge=*/8, /*gap=*/10, /*gap_voxels=*/2);
  const auto m = c.extended();
  EXPECT_EQ(m[c.at(8)], 1);
  EXPECT_EQ(m[c.at(9)], 1);
  for (std::size_t z = 10; z < 24; ++z) EXPECT_EQ(m[c.at(z)], 0) << "the gap and the fossa's roof stay out: " << z;
}

TEST(AtlasZone, LeavesBoneWithNoRoofOrTooFarBelowIt) {
  // Brain over a fossa's roof the zone cut into: no bone above the gap.
  EXPECT_EQ(Column(8, 10, 2, /*roof=*/false).extended()[Column(8, 10, 2).at(8)], 0);
  // A gap longer than kJointGapMaxMm (4 voxels = 6 mm): not the joint space.
  EXPECT_EQ(Column(8, 10, 4).extended()[Column(8, 10, 4).at(8)], 0);
  // Bone 4 voxels (6 mm) above the zone's edge: more than kZoneRimMm.
  EXPECT_EQ(Column(8, 12, 2).extended()[Column(8, 12, 2).at(8)], 0);
  // Up to 3 voxels (4.5 mm) and a 3-voxel gap (4.5 mm): added.
  EXPECT_EQ(Column(8, 11, 3).extended()[Column(8, 11, 3).at(10)], 1);
}

TEST(AtlasZone, TakesTheJointSpaceOnlyWhereAProcessMayStand) {
  const Column c(8, 10, 2);
  const std::size_t high = c.at(9);
  const auto m = c.extended([&](std::size_t i) { return i != high; });
  EXPECT_EQ(m[c.at(8)], 0) << "all of the column's bone, or none";
  EXPECT_EQ(m[high], 0);
}

TEST(AtlasZone, FollowsTheHeadsSuperiorDownTheGrid) {
  // The same column stored upside down (superior = decreasing z).
  Column up(8, 10, 2), down(8, 10, 2);
  for (std::size_t z = 0; z < 24; ++z) down.mask[down.at(z)] = up.mask[up.at(23 - z)], down.bone[down.at(z)] = up.bone[up.at(23 - z)];
  const auto m = ms::segmentation::extend_to_joint_space(down.mask, down.bone, down.dims, 2, -1, 1.5, [](std::size_t) { return true; });
  EXPECT_EQ(m[down.at(15)], 1);
  EXPECT_EQ(m[down.at(14)], 1);
  EXPECT_EQ(m[down.at(13)], 0);
}
