// Signed Angle Field and the SAF asymmetry scores (METHOD.md §3, §4.1-4.3).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/types.h"

namespace ms::asymmetry {

// C = ((a, b), (c, d)): the angle between ∇u_ab and ∇u_cd.
struct Configuration {
  std::string name;
  std::string a, b, c, d;
};
// The documented set of left configurations (docs/method.md), each mixing
// condyle, coronoid, angle and chin landmarks.
const std::vector<Configuration>& default_configurations();
Configuration mirrored(const Configuration& c);  // label mirror σ

// The SAF score is defined on the surface remeshed isotropically at this edge
// length (mm): on coarser triangulations the Dirichlet disks and per-face
// gradients add a discretisation floor (docs/method.md, "Resolution"), so the
// pipeline scores a 1 mm remeshing when the surface has another edge length.
constexpr double kSafEdgeMm = 1.0;

struct SafOptions {
  double disk_radius_mm = 2.0;
  double min_gradient_ratio = 1e-3;  // faces with |∇u| below this × median are masked
  // σ (mm) of the heat kernel that smooths each θ_C (circular mean) before the
  // per-vertex mirror comparison (docs/method.md); 0 = per face, METHOD.md's literal form.
  double smoothing_mm = 6.0;
  std::vector<Configuration> configurations = default_configurations();
  // Keep every θ_C the comparison used in SafResult::fields (per vertex when
  // smoothed, per face otherwise), for the SRD descriptors (srd.h).
  bool keep_fields = false;
};

// One signed angle field: configuration `name` of the set, as given (mirrored =
// false) or its label mirror σ(C) (mirrored = true); labels resolved in `config`.
struct AngleField {
  std::string name;
  bool mirrored = false;
  Configuration config;
  std::vector<double> theta;  // per vertex (smoothed) or per face; NaN where masked
};

struct SafResult {
  double score = -1;                       // §4.1, radians; -1 if not computed
  double correspondence_free = -1;         // §4.3, radians
  std::map<std::string, double> per_configuration;
  std::vector<double> per_vertex;          // SAF map (§4.2), radians
  std::vector<std::string> skipped;        // configurations with missing landmarks
  std::size_t factorisations = 0;
  LandmarkSet disk_centres;           // the anchors projected onto the surface
  std::vector<AngleField> fields;     // only with SafOptions::keep_fields
};

// θ_C per face, in (-π, π]; NaN where masked.
std::vector<double> signed_angle_field(const Mesh& mesh, const std::vector<Vec3>& g1, const std::vector<Vec3>& g2,
                                       double min_gradient_ratio = 1e-3);

// The Dirichlet disk centres the pipeline uses: for each detected landmark, its
// point in the symmetric reference configuration when use_reference (and the
// reference has it), else the detected point. Landmarks not detected stay out.
LandmarkSet saf_anchors(const LandmarkSet& detected, const LandmarkSet& reference, bool use_reference = true);

// Needs a closed outward mesh, landmarks (disk centres, projected onto the
// surface here) and the fitted symmetry plane.
SafResult compute_saf(const Mesh& mesh, const LandmarkSet& landmarks, const Plane& plane, const SafOptions& options = {});

// Wrap an angle to (-π, π].
double wrap_angle(double a);

}  // namespace ms::asymmetry
