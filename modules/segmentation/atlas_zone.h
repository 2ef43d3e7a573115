// The mandible by the placed atlas (docs/segmentation.md, "Identification
// and separation by the atlas"): the bone where the atlas's mandible
// probability is at least kAtlasZoneP, plus the bone beyond that zone that
// is attached to it and to nothing else.
#pragma once

#include <cstdint>
#include <functional>
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
// touches the zone and either has no voxel with p < kAtlasSupportP (a
// condyle or coronoid longer than the atlas's, standing free of the skull)
// or lies wholly where in_room(i) holds (when given).
// in_room: where a condyle or coronoid taller than every training
// mandible's may stand (docs/segmentation.md, step 3, "Processes past the
// support": the support grown by the fit's tolerance, above the atlas's
// sigmoid notch; segmentation.cpp). A coronoid tip the bone threshold cut
// from its process at ~4 mm voxels joins; an upper crown over the lower
// teeth (below the notch) does not, nor a piece fused to the arch or the
// skull base (it reaches beyond the grown support). It is asked only of the
// components that touch the zone and reach past the support, until one
// voxel is out.
std::vector<std::uint8_t> atlas_zone_mask(const std::vector<std::uint8_t>& bone, const std::vector<float>& p, const std::array<std::size_t, 3>& dims,
                                          const std::function<bool(std::size_t)>& in_room = {});

// The zone's rim (docs/segmentation.md, "the atlas's zone", step 3): where the
// similarity-placed atlas's p >= kAtlasZoneP ends inside a bone that goes on
// for a few millimetres and ends in soft tissue (a ramus, angle or body
// larger than 90 % of the training mandibles there, e.g. the longer side of
// an asymmetric mandible), the zone's edge cuts the cortex, and when that
// bone is fused to other bone it is no free appendix. The rim is the bone
// within kZoneRimMm plus one voxel of the mask (geodesic, through what is
// not soft tissue) that has no path of strictly increasing distance to
// tissue farther out, beyond the training mandibles' support (p <
// kAtlasSupportP) or on a face of the scanned part: bone that ends there in
// soft tissue, not bone that goes on (a fossa's roof, a zygomatic arch, a
// maxilla, the spine, which lie behind the voxels touching the mask).
// The similarity fit's residual: the atlas recovers a known pose within 3 mm
// (tests/atlas) and a population reaches a few millimetres beyond 90 training
// mandibles; the same tolerance checks the image separation's mask against
// the support (kSupportToleranceMm, segmentation.cpp). The extra voxel is the
// partial-volume voxel at a bone's edge, whose centre lies up to a voxel out.
constexpr double kZoneRimMm = 5.0;
// Soft tissue is at most this (HU): muscle 40-60, gland and fat below,
// unenhanced blood 30-45 (Hounsfield scale tables). Between it and the bone
// threshold lie bone blurred by partial volume (an upper tooth's root in
// thin alveolar bone at 4 mm voxels, the eminence beside a sigmoid notch) and
// contrast-filled vessels: the rim's bone must end below it, so that a
// fragment the bone threshold cut from its bone does not join.
constexpr double kSoftTissueMaxHu = 150.0;

// mask: the zone and its appendices (atlas_zone_mask); bone as there;
// not_soft: bone or above kSoftTissueMaxHu; p: the atlas's probability at
// every not_soft voxel; spacing in mm; faces: per axis, the first and last
// index of the scanned part (bone on a face may go on beyond it: a scan's
// end). Returns the mask with its rim added.
std::vector<std::uint8_t> add_zone_rim(const std::vector<std::uint8_t>& mask, const std::vector<std::uint8_t>& bone,
                                       const std::vector<std::uint8_t>& not_soft, const std::vector<float>& p,
                                       const std::array<std::size_t, 3>& dims, const std::array<double, 3>& spacing,
                                       const std::array<std::array<std::size_t, 2>, 3>& faces);

// The superior joint space, seen along the head's vertical. Where the voxels
// do not resolve the joint space across (coarse pixels: the zone and its rim
// end short of a condylar head welded to its fossa's roof by partial volume)
// the slices may still resolve it along the vertical: a column of voxels
// rising from the mask's top runs through bone, then through a gap of
// non-bone at most kJointGapMaxMm high, then into bone again (the fossa's
// roof). The bone between the mask and that gap is the condyle's top: the
// adult superior joint space is 2.5 +/- 0.5 mm (Ikeda & Kawamura 2009, limited
// cone-beam CT of 22 joints), so a gap up to twice it above the condyle is
// the joint, and a longer one (the brain over a fossa's roof the zone cut
// into, the temporalis over a coronoid) is not.
constexpr double kJointGapMaxMm = 5.0;

// mask: the zone, its appendices and rim; bone as for atlas_zone_mask; dims
// the grid; up_axis (0-2) and up_step (+1 or -1): the grid axis nearest to the
// placed atlas's superior and its direction; up_mm: that axis's spacing;
// in_room: where a process may stand (ProcessRoom, segmentation.cpp). Returns
// the mask plus, in each column along up_axis whose first voxel above the
// mask is bone, the bone up to a gap that satisfies the rule above, when that
// bone is at most kZoneRimMm high (the similarity fit's tolerance, as for the
// rim) and wholly in the room.
std::vector<std::uint8_t> extend_to_joint_space(const std::vector<std::uint8_t>& mask, const std::vector<std::uint8_t>& bone,
                                                const std::array<std::size_t, 3>& dims, int up_axis, int up_step, double up_mm,
                                                const std::function<bool(std::size_t)>& in_room);

}  // namespace ms::segmentation
