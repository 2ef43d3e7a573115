// The cranial mid-sagittal plane of a scan (METHOD.md §5, docs/method.md):
// bone above the condyles with the mandible left out (segmentation), its
// surface (surface), the mirror-ICP fit (reference). One composition shared by
// `mandisym run` and the tests.
#pragma once

#include "core/types.h"
#include "reference/reference.h"

namespace ms::pipeline {

struct CranialInputs {
  const Volume* ct = nullptr;
  const Mask* mandible = nullptr;  // on the CT's grid
  double threshold_hu = 250;       // bone threshold (after the scan's calibration offset)
  Plane mandible_plane;            // the mandible's symmetry plane: the fit's start and the floor's frame
  LandmarkSet landmarks;           // Co_L/Co_R set the floor; Me, Pog measured against the plane
  const Mesh* mandible_surface = nullptr;  // floor at its top when a condylion is missing
};

// Never throws: a failure is CranialResult::found = false with the reason.
reference::CranialResult fit_cranial_plane(const CranialInputs& in);

}  // namespace ms::pipeline
