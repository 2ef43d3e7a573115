// Segmentation QC figures: axial, coronal and sagittal slices through the
// mask's centre with the mask outlined, written as PNG (ITK PNG IO). Pure
// image code: works without a display.
#pragma once

#include <string>
#include <vector>

#include "core/types.h"
#include "landmarks/palate.h"

namespace ms::reports {

// Returns the paths written (dir/qc_axial.png, ...).
std::vector<std::string> write_qc_slices(const Volume& ct, const Mask& mask, const std::string& dir);

// Head-frame QC: the mid-sagittal slice (in the symmetry plane, anterior on the
// left, the scan's superior up) with the palatal line fitted to the nasal
// floor in cyan (dotted beyond its support) and Me / Pog in green. Returns
// false (nothing written) when the slice would be empty.
bool write_head_frame_slice(const Volume& ct, const Plane& midsagittal, const landmarks::PalatalPlane& palate,
                            const LandmarkSet& landmarks, const std::string& path);

}  // namespace ms::reports
