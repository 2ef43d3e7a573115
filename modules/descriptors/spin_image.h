// Local shape descriptors on a triangle mesh (docs/descriptors.md):
//  - the classic Spin Image (Johnson & Hebert 1997/1999): 2D histogram of
//    (alpha, beta) = (distance from the reference normal ray, signed height
//    over the tangent plane) of the neighbours within the support;
//  - the Improved Spin Image (Zhang 2014, thesis ch. 3; ../shared/seed): the
//    beta axis replaced by the signed angle between the reference normal and
//    the neighbour's normal, positive when the neighbour's normal leans towards
//    the reference normal ray; every normal is the z axis of a repeatable local
//    reference frame (Tombari et al. 2010, the frame SHOT uses).
// Both use the support angle (neighbours whose normal is more than
// support_angle_deg from the reference normal are left out), bilinear
// interpolation into the bins, each neighbour weighted by its vertex area (so
// the histogram measures surface, not sampling density) and unit L2 norm.
// No ITK/VTK here; Eigen only inside the .cpp.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "core/types.h"

namespace ms::descriptors {

struct Options {
  double support_radius_mm = 0;   // neighbours within this distance of the reference vertex; 0 = 10 x mesh resolution
  int bins = 15;                  // the image is bins x bins (descriptor length bins^2)
  double support_angle_deg = 90;  // neighbours whose normal deviates more than this are not used
  // Radius of the local reference frame at the reference vertex (its z axis is
  // the reference normal of the ISI); 0 = the support radius, as in SHOT.
  double lrf_radius_mm = 0;
  // Radius of the frames giving the ISI's neighbour normals; 0 = the support
  // radius (docs/descriptor-benchmark.md: best of R/4, R/2, R at 20 and 30 %
  // noise by a wide margin, second at 10 %).
  double normal_radius_mm = 0;
};

enum class Kind {
  kSpinImage,          // classic SI: rows alpha, columns beta in [-R, R]; area-weighted vertex normals
  kImprovedSpinImage,  // ISI: rows alpha, columns signed angle in [-support angle, +support angle]; LRF normals
};

// Local reference frame: right-handed orthonormal x, y, z; z is the normal.
struct Frame {
  Vec3 x{1, 0, 0}, y{0, 1, 0}, z{0, 0, 1};
};

// Mean edge length of the mesh (the "mesh resolution" the parameters scale with).
double mesh_resolution(const Mesh& mesh);

// Descriptors of one mesh. Builds a neighbour grid and per-vertex areas and
// normals once; frames for the ISI neighbour normals are computed on first use.
// The mesh is copied (scenes are small); thread-safe after construction except
// for the first ISI request.
class SpinImages {
 public:
  SpinImages(const Mesh& mesh, const Options& options = {});
  ~SpinImages();
  SpinImages(const SpinImages&) = delete;
  SpinImages& operator=(const SpinImages&) = delete;

  double resolution() const;       // mesh resolution (mm)
  double support_radius() const;   // resolved support radius (mm)
  int length() const;              // bins^2
  const Options& options() const;  // with every 0 resolved

  // The SHOT local reference frame at a vertex: eigenvectors of the
  // distance-weighted scatter of the neighbours within radius (x largest
  // eigenvalue, z smallest). Signs: z agrees with the mesh's outward normal
  // there (the surface is oriented, so this is unambiguous where SHOT's
  // majority vote is not); x points to where most of the weighted scatter lies.
  Frame frame(int vertex, double radius) const;

  // Descriptors at the given vertices, row-major (vertex k's descriptor starts
  // at k * length()). A vertex with no neighbour but itself gets zeros.
  std::vector<float> compute(Kind kind, const std::vector<int>& vertices) const;

  // The un-normalised image at one vertex for inspection and tests:
  // image[row * bins + col], rows = alpha bins, cols = beta / angle bins.
  std::vector<double> image(Kind kind, int vertex) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Signed angle of the ISI (radians): the angle between unit normals n (at the
// reference point p) and nx (at the neighbour x), positive when nx leans
// towards the normal ray of p (its component across the ray points back to
// the ray: a concave neighbourhood), negative when it leans away (convex).
double signed_normal_angle(const Vec3& p, const Vec3& n, const Vec3& x, const Vec3& nx);

}  // namespace ms::descriptors
