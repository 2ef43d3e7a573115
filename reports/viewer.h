// Interactive 3D viewer embedded in report.html: the mandible surface coloured
// by the mirror distance or the SAF map, landmarks with labels and the
// symmetry plane, drawn by a small hand-written WebGL script (reports/viewer.js,
// compiled in) from base64 arrays embedded in the page. No external URLs.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/types.h"

namespace ms::reports {

// Frame of the symmetry plane, as the static views use it: x = medio-lateral
// (the plane normal, towards the patient's left), y = superior, z = anterior,
// origin at the centre of the mesh's bounding box.
struct PlaneFrame {
  Vec3 origin{0, 0, 0};
  Vec3 x{1, 0, 0}, y{0, 0, 1}, z{0, -1, 0};
  Vec3 to_frame(const Vec3& p) const;
};
// superior: the head's (e.g. the palatal plane's normal), made orthogonal to the normal.
PlaneFrame plane_frame(const Mesh& mesh, const Plane& plane, const Vec3& superior = Vec3{0, 0, 1});

// What the viewer draws, in the plane frame.
struct ViewerMesh {
  std::vector<float> positions;        // 3 per vertex
  std::vector<std::uint32_t> triangles;  // 3 per face
  std::vector<float> mirror, saf;      // 1 per vertex
  std::size_t source_faces = 0;        // faces before decimation
};

// Decimates the surface to at most max_faces triangles (VTK quadric
// clustering) when it has more; each kept vertex takes the values of the
// nearest source vertex. mirror and saf are per source vertex (a missing or
// mis-sized array reads as zeros). Positions are mapped into frame.
ViewerMesh viewer_mesh(const Mesh& mesh, const std::vector<double>& mirror, const std::vector<double>& saf,
                       const PlaneFrame& frame, std::size_t max_faces = 30000);

struct ViewerOptions {
  double mirror_lo = -3, mirror_hi = 3;  // mm, symmetric so 0 is white (same scale as the static views)
  double saf_lo = 0, saf_hi = 0.25;      // rad
};

// The report section: controls, canvas, legend, the data block and the
// script. plane and landmarks are in LPS; they are mapped into frame here.
std::string viewer_section_html(const ViewerMesh& vm, const PlaneFrame& frame, const Plane& plane,
                                const LandmarkSet& landmarks, const ViewerOptions& options = {});

// Base64 of little-endian binary arrays, as the viewer decodes them.
std::string base64_le(const std::vector<float>& values);
std::string base64_le(const std::vector<std::uint32_t>& values);

// The viewer script (reports/viewer.js), as compiled in.
const char* viewer_script();

}  // namespace ms::reports
