// Symmetry plane and symmetric reference configuration (METHOD.md §5), Ceres.
// Stage 1: robust least squares between the detected landmarks and a
// configuration that is exactly symmetric about the plane (one free point per
// bilateral pair, its partner its reflection; midline points on the plane).
// Stage 2: mirror-ICP on the surface: reflected vertices to the surface,
// point-to-plane residuals, Huber loss, a few correspondence rounds.
#pragma once

#include <array>
#include <map>
#include <string>
#include <vector>

#include "core/types.h"

namespace ms::geometry {
class ClosestPointIndex;
}

namespace ms::reference {

struct Options {
  double landmark_huber_mm = 2.0;   // Huber scale of the landmark residuals
  bool refine_on_surface = true;    // run mirror-ICP after the landmark fit
  int icp_rounds = 5;
  std::size_t icp_samples = 4000;   // surface vertices used per round
  double icp_huber_mm = 1.0;
  double icp_cauchy_mm = 0.25;      // scale of the redescending rounds after the Huber rounds (0 = none)
  Vec3 superior{0, 0, 1};           // the head's superior (LPS) for the asymmetry vectors' frame
};

struct Result {
  Plane plane;                          // normal points to the patient's left
  LandmarkSet reference;                // symmetric reference configuration
  double rms_landmark_residual_mm = 0;  // detected vs reference
  double surface_rms_mm = -1;           // mirror-ICP point-to-plane RMS (-1: not run)
  // detected - reference, in the plane frame: {medio-lateral (+left),
  // antero-posterior (+posterior), supero-inferior (+superior)}
  std::map<std::string, Vec3> asymmetry_vectors;
  std::vector<std::string> warnings;
};

// Needs at least one bilateral pair; throws ms::Error(GeometryFailed) otherwise.
Result fit(const LandmarkSet& detected, const Mesh* surface, const Options& options = {});

// Stage 2 alone: mirror-ICP of surface about a plane, from initial (converges
// from about 20 degrees off). rms_mm (optional): final point-to-plane RMS.
// index (optional): the surface's closest-point index, when the caller has one.
Plane refine_plane_on_surface(const Mesh& surface, const Plane& initial, const Options& options = {},
                              double* rms_mm = nullptr, const geometry::ClosestPointIndex* index = nullptr);

// Cranial mid-sagittal plane (METHOD.md §5, optional): the cranium's own
// mirror plane, by the same mirror-ICP from the mandible's plane, and where the
// mandible sits against it — positional asymmetry (the mandible shifted or
// turned against the skull) apart from shape asymmetry (the mandible itself).
struct CranialResult {
  bool found = false;
  std::string reason;                 // why not, when not found
  Plane plane;                        // normal points to the patient's left
  double surface_rms_mm = -1;         // mirror-ICP residual on the cranium surface
  double bone_volume_cm3 = 0;         // cranium used
  double angle_to_mandible_plane_deg = 0;
  // Signed distance (+ patient left) of midline landmarks (Me, Pog) and of the
  // midpoint of the condylions to the cranial plane and to the mandible's own plane.
  std::map<std::string, double> to_cranial_mm, to_mandible_mm;
};
// cranium: closed surface of the cranium (bone above the condyles, mandible
// excluded); volume_cm3: its bone volume. Refuses (found = false) with less
// than 50 cm3 or when one side of the mandible's plane holds under a quarter of it.
CranialResult cranial_plane(const Mesh& cranium, double volume_cm3, const Plane& mandible_plane, const LandmarkSet& landmarks,
                            const Options& options = {});

// Rigid transform x -> R x + t (R row-major).
struct RigidTransform {
  std::array<double, 9> R{1, 0, 0, 0, 1, 0, 0, 0, 1};
  Vec3 t{0, 0, 0};
  Vec3 apply(const Vec3& x) const;
  RigidTransform inverse() const;
};

struct AlignResult {
  RigidTransform transform;   // moving -> fixed
  double rms_mm = 0;          // point-to-plane RMS of the inlier half of the last round
  std::size_t landmark_pairs = 0;  // landmarks used for the initial guess
};

// Aligns a surface to another of the same bone (pre/post surgery): Kabsch on
// the landmarks both sets have (at least 3; otherwise the centroids), then
// point-to-plane ICP with a Cauchy loss (scale cauchy_mm) so that the parts
// that really changed do not drag the fit.
AlignResult align_rigid(const Mesh& moving, const Mesh& fixed, const LandmarkSet& lm_moving, const LandmarkSet& lm_fixed,
                        int rounds = 12, double cauchy_mm = 1.0);
// The same ICP from a given initial transform (moving -> fixed).
AlignResult align_rigid_from(const Mesh& moving, const Mesh& fixed, const RigidTransform& initial, int rounds = 12,
                             double cauchy_mm = 1.0);
// ... with the fixed surface's closest-point index and face normals built once
// by the caller (many patches aligned to one surface).
AlignResult align_rigid_from(const Mesh& moving, const geometry::ClosestPointIndex& fixed_index,
                             const std::vector<Vec3>& fixed_face_normals, const RigidTransform& initial, int rounds = 12,
                             double cauchy_mm = 1.0);

// Least-squares rigid transform taking each pair's first point onto its
// second (Kabsch / Umeyama without scale; reflections excluded). Identity for
// no pairs.
RigidTransform kabsch(const std::vector<std::pair<Vec3, Vec3>>& pairs);

// Orthonormal frame of a symmetry plane: e_ml = normal, e_si = `superior`
// (default: the scan's +S) projected into the plane, e_ap = e_si x e_ml
// (posterior).
void plane_frame(const Plane& plane, Vec3& e_ml, Vec3& e_ap, Vec3& e_si, const Vec3& superior = Vec3{0, 0, 1});

}  // namespace ms::reference
