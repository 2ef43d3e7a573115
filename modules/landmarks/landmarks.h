// Anatomical landmarks on the mandible surface (METHOD.md §2, docs/landmarks.md).
// Pose-robust: the mandible's own symmetry plane (mirror-ICP from the scan's
// sagittal plane) gives left/right and the medio-lateral axis; geodesic
// extremities (local maxima of the average geodesic distance) find the
// condylar and coronoid processes whatever the head pose; the bilateral
// tangents of the ramus and lower border give the gonial angle.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/types.h"
#include "landmarks/palate.h"

namespace ms::landmarks {

struct Options {
  int agd_samples = 24;             // farthest-point samples for the average geodesic distance
  double extremity_radius_mm = 15;  // an extremity is the AGD maximum within this geodesic radius
  double process_radius_mm = 10;    // Co / Cr: highest point within this geodesic radius of the extremity
  double apex_radius_mm = 4;        // extreme points refined by a quadratic fit over this radius
  // When set, landmarks within 1.5 voxels of a face of this grid are reported
  // missing (the mandible is cut there: the extreme point is not in the scan).
  const Geometry* scan_grid = nullptr;
  // The head's superior direction (LPS). "Most superior", "lowest" and "most
  // anterior" are taken in the symmetry plane's frame built on it. Default:
  // the scan's +S (head pitch then moves Me, Cr and Pog); the pipeline passes
  // the palatal plane's normal (palate.h).
  Vec3 superior{0, 0, 1};
  // The mandible's symmetry plane when already fitted (mandible_plane()).
  std::optional<Plane> plane;
  // The placed atlas's mean condyle and coronoid tops (LPS mm, one of each
  // per side; atlas::process_tops carried by the fitted pose), when the atlas
  // was placed: which of the two a process lies nearer to antero-posteriorly
  // decides a process the posterior-border check alone cannot (step 3).
  std::vector<Vec3> atlas_condyles, atlas_coronoids;
};

struct Result {
  LandmarkSet landmarks;       // LPS mm; missing landmarks are absent
  std::vector<std::string> missing;
  // Why each missing landmark is missing (name -> one sentence; docs/landmarks.md, "Missing landmarks").
  std::map<std::string, std::string> why_missing;
  // Where a truncated scan cuts the mandible, in the head's frame: "top",
  // "bottom", "front", "back", "left side", "right side" (the patient's);
  // empty when the mandible lies inside the scan (docs/landmarks.md, step 6).
  std::vector<std::string> cut_at;
  std::vector<std::string> warnings;
  std::string method;
  Plane plane;                 // symmetry plane used for the labelling (normal to patient left)
  std::vector<Vec3> extremities;  // geodesic extremities found (diagnostics)
};

Result detect(const Mesh& mesh, const Options& options = {});

// The mandible's own symmetry plane (normal to the patient's left): mirror-ICP
// from the scan's sagittal plane through the centroid (head pose within
// about 20 degrees). detect() fits it unless Options::plane is given.
Plane mandible_plane(const Mesh& mesh);

// What `mandisym run` does: the mandible's plane, the palatal plane from the
// CT (palate.h), then detect() with its normal as superior — or the scan's
// superior when no palate is found, with a warning saying so. options.plane
// and options.superior are set here; `palate` (optional) receives the fit.
// `frame` (optional) receives the head frame used (HeadFrame's order).
Result detect_in_head_frame(const Volume& ct, const Mesh& mesh, Options options = {}, const PalateOptions& palate_options = {},
                            PalatalPlane* palate = nullptr, HeadFrame* frame = nullptr);

}  // namespace ms::landmarks
