// Mirror surface distance (METHOD.md §4.4, Cevidanes et al. 2011), anatomical
// regions, and bilateral landmark measures (§4.5).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/types.h"

namespace ms::asymmetry {

// Regions by geodesic Voronoi from landmark seeds (docs/method.md "Regions"):
// condyle = Co, coronoid = Cr, angle = Go, ramus = midpoint of Co–Go, body =
// midpoint of Go–Me (each snapped to the nearest vertex, per side), symphysis =
// Me and Pog. label[i] indexes names; -1 when no seed is available.
struct Regions {
  std::vector<int> label;
  std::vector<std::string> names;
};
Regions assign_regions(const Mesh& mesh, const LandmarkSet& landmarks);

// One third of the area of the faces around each vertex.
std::vector<double> vertex_areas(const Mesh& mesh);

struct DistanceStats {
  double mean_abs = 0, signed_mean = 0, rms = 0, p95 = 0, max = 0;  // max of |d|
  double max_outward = 0, max_inward = 0;  // largest d > 0 (bulging beyond the mirror) and largest -d
  double pct_area_over_1mm = 0, pct_area_over_2mm = 0;
};
DistanceStats distance_stats(const std::vector<double>& d, const std::vector<double>& w);

struct MirrorResult {
  std::vector<double> per_vertex;  // signed mm, + = this side bulges beyond its mirror
  DistanceStats overall;
  std::map<std::string, DistanceStats> regions;
  // Signed distance at each landmark (its nearest vertex): which side bulges,
  // e.g. a condylion above its mirror image is > 0 on that side.
  std::map<std::string, double> at_landmarks;
};
MirrorResult mirror_distance(const Mesh& mesh, const Plane& plane, const Regions& regions,
                             const LandmarkSet* landmarks = nullptr);

// Area-weighted mean of a per-vertex value in each region.
std::map<std::string, double> regional_means(const std::vector<double>& values, const std::vector<double>& areas,
                                             const Regions& regions);

struct Bilateral {
  double L = 0, R = 0, diff = 0, ratio = 0;  // diff = L - R, ratio = L / R
};
// ramus_height_mm (Co–Go), body_length_mm (Go–Me), gonial_angle_deg (Co–Go–Me),
// condyle_to_plane_mm, gonion_to_plane_mm; a measure is absent when its
// landmarks are missing.
std::map<std::string, Bilateral> bilateral_measures(const LandmarkSet& landmarks, const Plane& plane);

}  // namespace ms::asymmetry
