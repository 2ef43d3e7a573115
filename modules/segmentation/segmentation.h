// Mandible segmentation (ITK). Thin first version: bone threshold, connected
// components, anatomical choice of the mandible component, hole filling.
// Issue C replaces the component choice with separation at the teeth and TMJ.
#pragma once

#include <string>
#include <vector>

#include "core/types.h"

namespace ms::segmentation {

struct Options {
  double bone_threshold_hu = 250.0;  // HU; cancellous bone is ~250-450, cortical > 1000
  double min_component_cm3 = 4.0;    // smaller components are never the mandible
};

struct Result {
  Mask mask;               // on the input grid
  std::string method;      // "auto" | "external"
  std::size_t voxels = 0;
  double volume_mm3 = 0;
  bool truncated = false;  // the mask touches the edge of the scan
  std::vector<std::string> warnings;
};

// Throws ms::Error(NoMandible) when no component qualifies.
Result segment_mandible(const Volume& ct, const Options& options = {});

// Mandible from an external label map (e.g. TotalSegmentator
// craniofacial_structures, mandible = 1): voxels equal to label (label < 0:
// any non-zero label, allowed only when the map holds a single label),
// resampled to the CT grid by nearest neighbour in LPS space. Throws
// ms::Error naming source: Usage (several labels and no label given),
// InputInvalid (no overlap with the CT), NoMandible (label empty on the CT).
Result from_label_map(const Geometry& ct_grid, const LabelMap& labels, int label, const std::string& source);

}  // namespace ms::segmentation
