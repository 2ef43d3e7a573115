// 3D views of the mandible for the report (VTK, offscreen under X/Xvfb):
// front, below, left and right, in the symmetry plane's frame, the surface
// coloured by a per-vertex value with a colour bar, landmarks as spheres and
// the symmetry plane as a translucent sheet.
#pragma once

#include <string>
#include <vector>

#include "core/types.h"

namespace ms::reports {

struct ColourMap {
  std::string title;      // colour bar title, e.g. "mirror distance (mm)"
  double lo = -3, hi = 3; // value range mapped onto the colours (clamped)
  bool diverging = true;  // blue-white-red around 0; otherwise white-to-red
};

struct RenderedViews {
  std::vector<std::string> files;  // PNG paths, one per view (prefix_front.png, ...)
  std::string error;               // empty when rendered
};

// One set of four views: the surface coloured by values (one per vertex;
// anything else renders it uncoloured) with colours, written as
// prefix_{front,below,left,right}.png.
struct ViewSet {
  const std::vector<double>* values = nullptr;
  ColourMap colours;
  std::string prefix;
};

// Every set through one window (one OpenGL context). Never throws: on failure
// every result carries the error and no file is kept.
std::vector<RenderedViews> render_view_sets(const Mesh& mesh, const std::vector<ViewSet>& sets, const LandmarkSet& landmarks,
                                            const Plane& plane, int width = 520, int height = 420,
                                            const Vec3& superior = Vec3{0, 0, 1});

// Writes prefix_{front,below,left,right}.png. Never throws: on failure the
// error says why (no display, no Xvfb, OpenGL failure) and no file is kept.
RenderedViews render_views(const Mesh& mesh, const std::vector<double>& values, const ColourMap& colours,
                           const LandmarkSet& landmarks, const Plane& plane, const std::string& prefix, int width = 520,
                           int height = 420);

}  // namespace ms::reports
