// Synthetic head CT with ground truth: the project's test fixture factory.
//
// The anatomy is an implicit (signed-distance) model in a head frame H:
// origin between the condylar heads, +x patient left, +y posterior, +z superior
// (LPS axes at zero pose). The model is posed into LPS by
//   p_lps = R s (p_H - pivot) + shift,   R = Rz(yaw) Rx(pitch) Ry(roll)
// (pivot: centre of the jaw region, so the grid centred on LPS 0 frames the
// jaw; s = PhantomParams::scale, about the head frame's origin), then
// rasterised with partial-volume coverage, optional Gaussian blur (scanner
// PSF) and Gaussian noise. Deterministic for a given seed.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "core/types.h"

namespace ms::phantom {

// Per-side modification; index 0 = patient left, 1 = patient right.
struct SideAsymmetry {
  double ramus_height_mm = 0;   // added to Co–Go height (condyle moves up with the ramus)
  double body_length_mm = 0;    // added to Go–Me length (angle and ramus move posteriorly)
  double gonial_angle_deg = 0;  // added to the gonial angle (ramus tilts back about the angle)
  double condyle_size_mm = 0;   // added to each axis of the condylar head
};

struct PhantomParams {
  Vec3 spacing{0.8, 0.8, 0.8};    // mm
  Vec3 fov_mm{150, 150, 140};     // grid extent; grid size = round(fov / spacing)
  double noise_hu = 15;           // Gaussian noise, standard deviation in HU
  double blur_mm = 0.4;           // Gaussian PSF sigma in mm (0 = none)
  double yaw_deg = 0, pitch_deg = 0, roll_deg = 0;  // about S, L, P axes (right-handed)
  Vec3 shift_mm{0, 0, 0};
  double occlusal_gap_mm = 1.0;   // between upper and lower teeth; 0 = touching
  double joint_space_mm = 2.5;    // between condylar head and glenoid fossa
  bool metal = false;             // amalgam fillings in the first molars, with streaks
  bool edentulous = false;        // no teeth in either jaw (alveolar bone kept)
  bool mirror = false;            // mirror the finished volume left<->right
  std::array<SideAsymmetry, 2> side{};  // [0] = left, [1] = right
  double chin_deviation_mm = 0;   // symphysis shift, + towards patient left
  // Size of the whole head model about the point between the condylar heads
  // (1 = the adult model, ~100 mm across the condyles; 0.7 a young child's).
  // Every length of the anatomy scales, the knobs above (gaps, joint space,
  // asymmetries) too: a ramus +4 at scale 0.8 is 3.2 mm longer. Pose, field of view, voxels,
  // blur, noise and metal streaks are the scanner's and do not scale.
  double scale = 1.0;
  // Bone of the mandible: cortical shell thickness and the two densities
  // (the adult model: 2 mm, 1600 HU over a 350 HU cancellous core).
  double cortex_mm = 2.0;
  double cortical_hu = 1600;
  double cancellous_hu = 350;
  // Tooth crowns scaled about their occlusal end (widths and height; 1 = the model's).
  double crown_scale = 1.0;
  std::uint64_t seed = 1;
};

// One member of the random anatomy family (docs/phantom.md, "Random
// anatomy"): `base` with its anatomy drawn from the ranges of adult
// mandibles, independently per side where anatomy differs between sides,
// from `anatomy_seed` (the scanner knobs of `base` are kept). The same
// seed gives the same member.
PhantomParams random_anatomy(std::uint64_t anatomy_seed, PhantomParams base = {});

struct AsymmetryTruth {
  // The knobs as applied to the anatomy after mirroring (so "left" is the
  // patient's left of the output volume).
  std::array<SideAsymmetry, 2> side{};
  double chin_deviation_mm = 0;
  // Bilateral distances measured on the ground-truth landmarks.
  double ramus_height_L = 0, ramus_height_R = 0;  // Co–Go
  double body_length_L = 0, body_length_R = 0;    // Go–Me
};

struct Phantom {
  Volume ct;            // HU
  Mask mandible;        // ground-truth mandible incl. lower teeth, on the CT grid
  LandmarkSet landmarks;  // METHOD.md §2 names, LPS mm
  Plane plane;          // true symmetry plane of the unmodified anatomy (normal to patient left)
  Vec3 superior{0, 0, 1};  // the head frame's superior axis in LPS (the palate is perpendicular to it)
  AsymmetryTruth truth;
  PhantomParams params;
};

// Generates the phantom. Throws std::invalid_argument naming a bad parameter.
Phantom generate(const PhantomParams& params);

}  // namespace ms::phantom
