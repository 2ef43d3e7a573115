// Segmentation QC figures: axial, coronal and sagittal slices through the
// mask's centre with the mask outlined, written as PNG (ITK PNG IO). Pure
// image code: works without a display.
#pragma once

#include <string>
#include <vector>

#include "core/types.h"

namespace ms::reports {

// Returns the paths written (dir/qc_axial.png, ...).
std::vector<std::string> write_qc_slices(const Volume& ct, const Mask& mask, const std::string& dir);

}  // namespace ms::reports
