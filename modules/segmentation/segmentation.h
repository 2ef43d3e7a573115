// Mandible segmentation (ITK): calibration-robust bone threshold, separation
// of the mandible from skull, teeth, spine and hyoid by marker-based watershed
// on the bone distance map, anatomical identification, hole filling
// (docs/segmentation.md).
#pragma once

#include <string>
#include <vector>

#include "atlas/atlas.h"
#include "core/types.h"

namespace ms::segmentation {

struct Options {
  double bone_threshold_hu = 250.0;  // HU; cancellous bone is ~250-450, cortical > 1000
  double min_component_cm3 = 4.0;    // smaller components are never the mandible
  // HU (before the calibration offset) of the mandible's outer surface: about
  // half-way between soft tissue (~40) and cortical bone (~1200-2000). Used
  // when voxels are at most 1.25 mm; coarser scans keep the bone threshold.
  double surface_threshold_hu = 700.0;
  // HU (before the calibration offset) of dense bone (cortex, enamel) used for
  // the separation markers; partial-volume valleys between teeth in occlusion
  // and across a narrow joint space fall below it.
  double dense_threshold_hu = 1000.0;
  // Inputs finer than this (mm) are separated on a bin-averaged grid of about
  // this spacing; the surface is still placed at full resolution.
  double separation_spacing_mm = 0.6;
  // Inputs with at least 4 voxels per block of about this spacing (mm) are
  // first segmented on a bin-averaged grid of it to locate the mandible; the
  // full-resolution work then runs on the scan cropped to the located
  // mandible's box grown by locate_margin_mm (0 = never; docs/segmentation.md).
  double locate_spacing_mm = 1.0;
  double locate_margin_mm = 10.0;
  // The crop's mask may lie outside the located region (grown by one coarse
  // voxel) by at most this fraction; more, and the whole scan is segmented.
  double locate_outside_fraction = 0.1;
  // Axes coarser than this (mm) are interpolated (trilinear) to it for the
  // whole segmentation; the mask is brought back to the input grid.
  double max_working_spacing_mm = 2.0;
  // Watershed regions up to this size (cm3) that touch the mandible's region
  // more than any other region are joined to it: tooth crowns or thin
  // processes whose neck the core depth cut off (docs/segmentation.md).
  double fragment_merge_cm3 = 4.0;
  // ... or up to this fraction of the mandible's own region, if larger.
  double fragment_merge_fraction = 0.1;
  // A crown follows its root: pieces of other regions nearer (through bone)
  // to the mandible's core than to any other large core join the mandible
  // when they hold a voxel at least this deep (mm): a crown, not a thin plate
  // (docs/segmentation.md, step 5; 0 = never). On scans that resolve teeth.
  double crown_min_depth_mm = 2.0;
  // Beyond the band around the mandible's core, thick parts of its region are
  // kept up to this distance (mm) from the core: crowns whose thin dense shell
  // left no core, and the thin ramus plate and processes when the deeper cores
  // of teeth in occlusion leave little core in the ramus (8 mm, a crown's
  // height, cut a condylar process off; docs/segmentation.md).
  double thick_reach_mm = 20.0;
  // Identify the mandible by the mandible atlas placed in the scan
  // (docs/atlas.md); false, or when the atlas does not fit: by size and
  // position (docs/segmentation.md, step 4).
  bool use_atlas = true;
};

struct Result {
  Mask mask;               // on the input grid
  std::string method;      // "auto" | "external"
  std::size_t voxels = 0;
  double volume_mm3 = 0;
  bool truncated = false;  // the mask touches the edge of the scan
  // The scanned part of the input grid, whose faces are the scan's edge: the
  // whole grid, but for slabs of constant padding at its faces on scans up to
  // 2 mm (docs/segmentation.md, "Padding is not scanned").
  Geometry scanned_grid;
  bool cropped = false;    // full-resolution work ran on a crop around the located mandible
  // Scans up to 2 mm with the atlas placed: Dice between the image
  // separation's mask and the atlas zone's when the atlas did not verify the
  // image's and the zone was taken (two independent estimates; docs/qc.md,
  // separations_agree); -1 when they were not compared.
  double image_zone_dice = -1;
  // ... and when the atlas verified the image's mask and it was taken: Dice
  // between it and the atlas zone's on the zone check's grid (~1 mm;
  // docs/qc.md, image_agrees_with_zone); -1 when not compared.
  double taken_image_zone_dice = -1;
  // When image_zone_dice was measured: the area (mm2) of the cheek-teeth
  // columns where the scan runs in dense bone through enamel from the
  // atlas's zone to at least kWeldRiseMm above it, i.e. upper
  // teeth welded to the lower ones (occlusion.h), when it covers at least a
  // molar's occlusal table; else 0. The quality gate names it (docs/qc.md).
  double welded_occlusion_mm2 = 0;
  // ... and the weld was cut at the occlusal plane, but the atlas refused the
  // image's separation of the cut scan as well (other bone joined elsewhere).
  bool occlusion_cut_refused = false;
  double threshold_hu = 0;          // bone threshold used (after calibration offset)
  // HU level at which the mask's outer boundary was placed (after the
  // offset), on scans that resolve the cortex (voxels up to 1.25 mm: the
  // half-maximum between soft tissue and cortex); 0 otherwise and for
  // external masks. The surface follows it between voxels (docs/surface.md).
  double surface_level_hu = 0;
  double offset_hu = 0;             // estimated calibration offset (soft-tissue peak - 40 HU)
  double separation_radius_mm = 0;  // core depth used to separate the mandible (0: failed)
  std::string marker_source;        // "dense bone", "bone", or empty when separation failed
  // The mandible atlas placed in the scan (found = false: not used), and the
  // agreement of the mask with it: soft Dice 2 sum_mask(p) / (|mask| + sum(p))
  // of the mask with the atlas's probability p, on the mask's grid (-1: not computed).
  atlas::Fit atlas;
  double atlas_agreement = -1;
  // The mask's atlas evidence (sum of p) on the weaker side of the atlas's
  // mid-sagittal plane over that on the stronger, [0, 1] (-1: not computed):
  // near 1 for a whole mandible, low when a half is missing (docs/qc.md).
  double atlas_halves_balance = -1;
  std::vector<std::string> warnings;
};

// Throws ms::Error(NoMandible) when no component qualifies.
Result segment_mandible(const Volume& ct, const Options& options = {});

// The last step of segment_mandible (docs/segmentation.md, "Skull base welded
// to a condyle"): per side, the part of r.mask above the first slice (above
// the chin) where the side widens beyond twice its median cross-section there
// is removed when it runs to the top of the scan, or of the body where empty
// slices pad the volume; voxels, volume, truncation and warnings follow.
// Needs grid axes within ~25 degrees of left-right and superior-inferior.
void trim_welded_skull_base(const Volume& ct, Result& r);

// Mandible from an external label map (e.g. TotalSegmentator
// craniofacial_structures, mandible = 1): voxels equal to label (label < 0:
// any non-zero label, allowed only when the map holds a single label),
// resampled to the CT grid by nearest neighbour in LPS space. Throws
// ms::Error naming source: Usage (several labels and no label given),
// InputInvalid (no overlap with the CT), NoMandible (label empty on the CT).
Result from_label_map(const Geometry& ct_grid, const LabelMap& labels, int label, const std::string& source);

}  // namespace ms::segmentation
