// Mandible atlas: where the mandible is in a head CT, learned from real
// mandibles (docs/atlas.md).
//
// The atlas is two probability volumes in one frame (LPS axes, mm, origin at
// the training mandibles' mean centroid): `context`, the mean bone fraction of
// the training heads around their mandibles (mandible, maxilla, teeth, skull
// base, cervical spine), and `mandible`, the fraction of training mandibles
// covering each voxel. Both are mirror-symmetric (left/right is unknown in the
// training data). scripts/build-atlas makes it from ../shared/data/openkbp-train
// (folds 1-4 of scripts/cohort-folds.csv); the result is compiled into the
// binary (atlas::shipped()).
//
// fit() places the atlas in a scan: a similarity pose (translation, three
// angles, isotropic scale) that maximises the normalised cross-correlation of
// `context` with the scan's bone fraction, found by a coarse exhaustive
// search and a pattern search. Mirror poses (the atlas flipped
// superior-inferior and/or antero-posterior) are searched too: when one fits
// clearly better, the scan's declared orientation is likely wrong.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/types.h"

namespace ms::atlas {

// Axis-aligned LPS grid: voxel (i, j, k) is at origin + spacing * (i, j, k).
struct Grid {
  std::array<int, 3> n{0, 0, 0};
  double spacing = 3.0;  // mm
  Vec3 origin{0, 0, 0};  // LPS mm of voxel (0, 0, 0)
  std::size_t count() const { return static_cast<std::size_t>(n[0]) * n[1] * n[2]; }
  std::size_t linear(int i, int j, int k) const { return static_cast<std::size_t>(i) + static_cast<std::size_t>(n[0]) * (j + static_cast<std::size_t>(n[1]) * k); }
};

// Values on a grid; NaN marks voxels outside the scanned field of view.
struct Field {
  Grid grid;
  std::vector<float> v;
  // Trilinear value at an LPS point; NaN outside the grid or next to an unknown voxel.
  float at(const Vec3& p) const;
};

struct Atlas {
  Grid grid;                   // atlas frame
  std::vector<float> context;  // mean bone fraction, [0, 1]
  std::vector<float> mandible; // mandible probability, [0, 1]
  int cases = 0;               // training scans (before mirroring)
  std::string source;          // what it was built from
};

// Similarity pose atlas -> scan: p = t + scale * Rz(yaw) Rx(pitch) Ry(roll) * M a,
// with M = diag(1, ±1, ±1) the mirror flips (flip bit 1: antero-posterior,
// bit 2: superior-inferior). Angles in radians.
struct Pose {
  Vec3 t{0, 0, 0};
  double pitch = 0, yaw = 0, roll = 0;
  double scale = 1;
  int flip = 0;
  Vec3 apply(const Vec3& a) const;    // atlas -> scan
  // The atlas's superior axis in the scan (unit, LPS): the training heads'
  // mean superior direction carried by the pose.
  Vec3 superior() const;
  // The normal of the atlas's mid-sagittal plane in the scan (unit, LPS; the
  // atlas is mirror-symmetric, so its sign carries no meaning).
  Vec3 lateral() const;
  // The atlas's mid-sagittal plane in the scan: the atlas's frame is
  // mirror-symmetric about x = 0, which the pose carries to t.
  Plane midsagittal() const;
  Vec3 inverse(const Vec3& p) const;  // scan -> atlas
};

// Result of fitting the atlas to a scan.
struct Fit {
  bool found = false;   // a pose with ncc >= kMinFitNcc and enough of the atlas in the scan
  Pose pose;            // best upright pose (flip 0)
  double ncc = -1;      // its normalised cross-correlation, [-1, 1]
  double coverage = 0;  // fraction of the atlas box inside the scanned field of view
  Pose mirrored;        // best pose with a flip (orientation check)
  double mirrored_ncc = -1;
  double seconds = 0;   // fit_ct: bone fraction and search
};

// Below this NCC the atlas is taken as not found in the scan (docs/atlas.md).
constexpr double kMinFitNcc = 0.35;
// A pose must keep at least this fraction of the atlas box inside the scan to
// be scored; when none does, Fit::ncc stays below -1.
constexpr double kMinCoverage = 0.5;

// A scan's left-right mirror as a flip of its array axis nearest to the
// L-R (LPS x) axis, about the scan's centre: voxel i of that axis trades
// places with voxel n - 1 - i. In LPS it is the reflection p -> m p + b.
struct ScanMirror {
  int axis = 0;
  double m[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  Vec3 b{0, 0, 0};
  Vec3 apply(const Vec3& p) const;
};
ScanMirror lr_mirror(const Geometry& g);

// The atlas placed by pose p, then mirrored by s: as a pose, since the atlas
// is mirror-symmetric (its frame's x flip leaves it unchanged).
Pose mirror(const Pose& p, const ScanMirror& s);

// Bone fraction (HU >= bone_hu) of a CT on an axis-aligned LPS grid of the
// given spacing covering the scan, Gaussian-blurred with sigma blur_mm (0:
// none); voxels the scan does not reach are NaN.
Field bone_fraction(const Volume& ct, double spacing_mm, double bone_hu, double blur_mm);
// The same for a binary mask (fraction of the grid voxel covered).
Field mask_fraction(const Mask& m, double spacing_mm, double blur_mm);

// A scan's own frame: LPS turned about the grid's centre so that the array
// axes lie along the LPS axes nearest to them (world = q (x - centre) +
// centre; q the identity for a scan stored along the LPS axes). geom is the
// scan's geometry in the frame. When two array axes are nearest to one LPS
// axis (a turn near 45 degrees) the frame is LPS itself.
struct ScanFrame {
  double q[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  Vec3 centre{0, 0, 0};
  Geometry geom;
  Vec3 to_world(const Vec3& x) const;
  Vec3 from_world(const Vec3& p) const;
  Pose to_world(const Pose& p) const;
};
ScanFrame scan_frame(const Geometry& g);

// Fits atlas to a scan's bone fraction field (bone_fraction at the atlas's
// spacing, blurred by kFieldBlurMm).
Fit fit(const Atlas& atlas, const Field& scan_bone);
// The shipped atlas fitted to a scan and to its mirror (lr_mirror), the two
// poses combined (docs/atlas.md, "Mirror symmetrisation"): the fit of a
// mirrored scan is then the mirror of the fit. Fitted in the scan's frame,
// then carried to LPS: the same voxels turned in their file about their
// centre give the same fit, turned.
Fit fit_ct(const Volume& ct, double bone_hu);

// Two fits of one scan combined: fits `a` (the scan) and `b_mirrored` (its
// mirror, carried back by s) agree within kPoseAgreementMm and
// kPoseAgreementDeg: their mean pose (translation, geometric-mean scale,
// rotation midpoint) and mean NCC; otherwise the one with the higher NCC.
Fit combine_mirror_fits(const Fit& a, const Fit& b_mirrored, const ScanMirror& s);
// Two fits agree when the atlas centre moves less than this (two atlas
// voxels: twice the pattern search's starting step, 3 mm, on the 6 mm
// template points; a different optimum lies a coarse-search cell, 12 mm, away)...
constexpr double kPoseAgreementMm = 6.0;
// ...and the atlas axes turn less than this (twice that step's 3 degrees).
constexpr double kPoseAgreementDeg = 6.0;

// Blur (mm) applied to every bone-fraction field, in training and at run time.
constexpr double kFieldBlurMm = 3.0;

// Refines pose so that `values` (on the atlas grid) correlates best with
// field; coarse-to-fine pattern search over the seven parameters. Used by
// fit() and by the atlas builder (values = the mandible probability, field =
// a training mandible's mask fraction).
Pose refine(const Grid& grid, const std::vector<float>& values, const Field& field, Pose start, double* ncc_out);

// The atlas's mandible probability placed in a scan by a pose. The inverse
// pose is composed once, so a sample is one affine map and a trilinear
// lookup (it is taken at every bone voxel of a crop).
class MandiblePrior {
 public:
  MandiblePrior(const Atlas& atlas, const Pose& pose);
  double at(const Vec3& lps) const;  // 0 outside the atlas box
  // Sum of p times the voxel volume under the pose (mm3): the atlas's mandible volume.
  double mass_mm3() const { return mass_mm3_; }

 private:
  Field p_;
  double inv_[9];
  Vec3 t_;
  double mass_mm3_ = 0;
};

// Height of the atlas's sigmoid notch (mm along the atlas frame's superior
// axis from its origin, the training mandibles' mean centroid): the lowest
// axial level of the topmost run of levels where one half (x > 0) of the
// mean mandible (p >= 0.5) is two pieces, a coronoid process in front and a
// condyle behind. NaN when the halves never split. Measured on the shipped
// atlas: 30 mm (condyle top 39 mm, coronoid top 33 mm; 3 mm levels).
double sigmoid_notch_height(const Atlas& atlas);

// The tops of the atlas's mean condyle and coronoid process on its x > 0 half
// (atlas frame, mm; the x < 0 half is their mirror, x -> -x): the two largest
// pieces (26-connected) of the mean mandible (p >= 0.5) above the sigmoid
// notch, the posterior one the condyle; each top is the centroid of the
// piece's voxels on its highest level. NaN coordinates when the halves never
// split. Measured on the shipped atlas: 25 mm apart antero-posteriorly, the
// condyle's top 6 mm higher.
struct ProcessTops {
  Vec3 condyle, coronoid;
};
ProcessTops process_tops(const Atlas& atlas);

// The atlas compiled into this binary.
const Atlas& shipped();

// Serialised form (zlib-compressed; values quantised to 1/255).
std::vector<std::uint8_t> serialise(const Atlas& atlas);
Atlas deserialise(const std::uint8_t* data, std::size_t size);

}  // namespace ms::atlas
