// Anatomical landmarks on the mandible surface (METHOD.md §2, docs/landmarks.md).
// Pose-robust: the mandible's own symmetry plane (mirror-ICP from the scan's
// sagittal plane) gives left/right and the medio-lateral axis; geodesic
// extremities (local maxima of the average geodesic distance) find the
// condylar and coronoid processes whatever the head pose; the bilateral
// tangents of the ramus and lower border give the gonial angle.
#pragma once

#include <string>
#include <vector>

#include "core/types.h"

namespace ms::landmarks {

struct Options {
  int agd_samples = 24;             // farthest-point samples for the average geodesic distance
  double extremity_radius_mm = 15;  // an extremity is the AGD maximum within this geodesic radius
  double process_radius_mm = 10;    // Co / Cr: highest point within this geodesic radius of the extremity
  double apex_radius_mm = 4;        // extreme points refined by a quadratic fit over this radius
  // When set, landmarks within 1.5 voxels of a face of this grid are reported
  // missing (the mandible is cut there: the extreme point is not in the scan).
  const Geometry* scan_grid = nullptr;
};

struct Result {
  LandmarkSet landmarks;       // LPS mm; missing landmarks are absent
  std::vector<std::string> missing;
  std::vector<std::string> warnings;
  std::string method;
  Plane plane;                 // symmetry plane used for the labelling (normal to patient left)
  std::vector<Vec3> extremities;  // geodesic extremities found (diagnostics)
};

Result detect(const Mesh& mesh, const Options& options = {});

}  // namespace ms::landmarks
