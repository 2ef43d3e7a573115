// The cranium for the cranial mid-sagittal plane (METHOD.md §5, optional):
// bone above a floor plane (the condylar level), away from the mandible, on a
// coarse grid, largest connected part. Plain loops, no ITK.
#pragma once

#include "core/types.h"

namespace ms::segmentation {

struct CraniumOptions {
  double threshold_hu = 250;   // bone threshold (after the scan's calibration offset)
  double voxel_mm = 1.0;       // working grid: blocks of the input averaged to about this spacing
  double exclusion_mm = 4.0;   // bone this close to the mandible is left out (teeth, joints)
  Plane floor;                 // bone on the side of floor.normal is kept (normal pointing superior)
};

struct Cranium {
  Mask mask;                   // on the coarse grid
  double volume_cm3 = 0;       // of the kept component
};

Cranium cranium_mask(const Volume& ct, const Mask& mandible, const CraniumOptions& options);

}  // namespace ms::segmentation
