// The mandible by the placed atlas (docs/segmentation.md, "Identification
// and separation by the atlas"): the bone where the atlas's mandible
// probability is at least kAtlasZoneP, plus the bone beyond that zone that
// is attached to it and to nothing else.
#pragma once

#include <cstdint>
#include <vector>

#include <array>

namespace ms::segmentation {

// The zone: bone where at least 10 % of the training mandibles lie once the
// atlas is placed by similarity (docs/atlas.md). Chosen on folds 1-4 of
// openkbp-train (mean Dice 0.860 at 0.1, 0.854 at 0.15, 0.845 at 0.2; the
// Visible Human female 0.945 / 0.932 / -) and kept low: the zone must hold
// mandibles larger or longer than the mean.
constexpr double kAtlasZoneP = 0.1;
// Outside the training mandibles' support: below this probability no
// training mandible (of 90, mirrored) reaches, within the atlas's 3 mm blur.
constexpr double kAtlasSupportP = 0.001;

// bone: 1 where a voxel is bone; p: the atlas's mandible probability at every
// bone voxel (any value elsewhere); dims: the grid. Returns 1 for the zone's
// bone and for every 26-connected component of the remaining bone that
// touches the zone and has no voxel with p < kAtlasSupportP (a condyle or
// coronoid longer than the atlas's, standing free of the skull), else 0.
std::vector<std::uint8_t> atlas_zone_mask(const std::vector<std::uint8_t>& bone, const std::vector<float>& p, const std::array<std::size_t, 3>& dims);

}  // namespace ms::segmentation
