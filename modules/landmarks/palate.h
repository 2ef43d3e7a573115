// The head's superior direction from the skull: the palatal plane.
//
// METHOD.md §2 defines Co / Cr as "most superior", Me as "lowest" and Pog as
// "most anterior": directions of the head, not of the scanner. The mandible's
// symmetry plane removes yaw and roll but says nothing about pitch (nodding),
// and a head pitched 20 degrees moves menton 10 mm along the flat lower border.
// The hard palate is in every maxillofacial scan, a few centimetres above the
// teeth, and its nasal surface (the nasal floor) runs along the palatal plane
// ANS-PNS, which is within a few degrees of the Frankfort horizontal in adults.
// Its normal within the mid-sagittal plane is the head's superior direction.
//
// Found from the CT alone, beside the mandible (docs/landmarks.md):
// para-sagittal intensity profiles 4-8 mm either side of the mandible's
// symmetry plane, from above the incisors to above the rami; on each, every
// top of a bone run with air (a closed cavity) or soft tissue above it is a
// nasal-floor candidate; the line (in the sagittal plane) through the most
// candidates within +-1.5 mm is found by an exhaustive slope/offset search,
// then refined by least squares. It is searched on the air candidates alone
// and on all of them, and the better supported line is kept (mucosa over the
// floor leaves the air candidates only a turbinate's edge higher up).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "core/types.h"

namespace ms::landmarks {

struct PalateOptions {
  // The palate is a plate 1-3 mm thick: at 3 mm voxels its peak reads ~250 HU,
  // well below cortical bone, so a candidate's peak only has to clear this.
  double plate_hu = 150;      // (add the scan's calibration offset)
  double air_hu = -400;       // air threshold (add the scan's calibration offset)
  double max_tilt_deg = 45;   // steeper lines are not searched
  double min_length_mm = 20;  // antero-posterior extent the supporting samples must span
  std::size_t min_samples = 20;
  double max_rms_mm = 1.5;
  // The head's superior direction from the mandible atlas's pose (atlas.h,
  // superior_axis), when the atlas was placed: a palatal line more than
  // max_atlas_deviation_deg from it is rejected (a nasal floor found on the
  // wrong structure), and it is the head frame when no palate is accepted.
  // 40 degrees: on openkbp-train folds 1-4 the accepted palatal normals lie
  // 12.5 degrees (median), 26 (95th percentile), at most 36.1 from it.
  std::optional<Vec3> atlas_superior;
  double max_atlas_deviation_deg = 40;
};

// The frame "superior" is taken in (docs/landmarks.md, "Head frame"), in the
// documented order: the palatal plane; else the mandible atlas's pose
// ("mandible": the atlas is placed on the mandible and the bone around it);
// else the scan's axes.
struct HeadFrame {
  Vec3 superior{0, 0, 1};        // unit, LPS
  std::string source = "scan_axes";  // "palatal" | "mandible" | "scan_axes"
  std::string why;               // why the palatal plane was not used (empty when it was)
};

struct PalatalPlane {
  bool found = false;
  std::string reason;       // why not, when not found
  Vec3 superior{0, 0, 1};   // unit, LPS: normal of the palatal line within the mid-sagittal plane, towards the vertex
  double tilt_deg = 0;      // palatal line vs the scan's axial plane; + = posterior end higher (head flexed, chin down)
  double rms_mm = 0;        // residual of the supporting samples about the line
  double length_mm = 0;     // antero-posterior extent of the supporting samples
  std::size_t samples = 0;  // supporting nasal-floor samples
  std::string floor;        // what is above the floor: "air" (patent airway) or "soft tissue" (filled cavity)
  Vec3 anterior{0, 0, 0}, posterior{0, 0, 0};  // ends of the fitted line over its support (LPS mm)
};

// `midsagittal`: the mandible's symmetry plane (normal to the patient's left);
// `mandible`: its surface, which says where the palate can be.
PalatalPlane find_palatal_plane(const Volume& ct, const Mesh& mandible, const Plane& midsagittal,
                                const PalateOptions& options = {});

}  // namespace ms::landmarks
