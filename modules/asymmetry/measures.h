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
  // d at each vertex's mirror point σ(v) (the closest surface point to its
  // reflection; barycentric): about −d(v), exactly so only where the two sides
  // are parallel.
  std::vector<double> at_mirror_point;
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

// The SAF map is symmetrised (a vertex and its mirror point carry nearly the
// same value), so it marks a left/right pair of places, not a side. The sided
// map gives each vertex its pair's value in proportion to how far the vertex
// lies beyond its mirror point: 2 w a with w = ½(1 + clamp(e / share_mm, −1, 1))
// and e = ½(d(v) − d(σ(v))) from the signed mirror distance — all of the pair's
// value where this side bulges by share_mm or more, none where it lies that far
// inside, half each where the sides agree. e is antisymmetric over a mutual
// pair (σ(σ(v)) = v), whose two shares then sum to its value. The side is a
// convention (the larger side), not a diagnosis: docs/method.md.
std::vector<double> sided_map(const std::vector<double>& pair_map, const MirrorResult& mirror, double share_mm = 1.0);

// Which side, and where: the sided map minus its value at the mirror point,
// l(v) = 2 a clamp(e / share_mm, -1, 1) (= 2 (sided - pair) where sigma is
// mutual): > 0 on the member of a pair that lies beyond its mirror, the
// opposite on the other, 0 where the sides agree. Its regional means are
// antisymmetric over a left/right region pair; the largest is the region where
// the larger side carries most of the SAF map's difference (docs/method.md).
std::vector<double> lateral_map(const std::vector<double>& pair_map, const MirrorResult& mirror, double share_mm = 1.0);

// The region with the largest value of a regional map ("" when empty).
std::string largest_region(const std::map<std::string, double>& regional);

struct Bilateral {
  double L = 0, R = 0, diff = 0, ratio = 0;  // diff = L - R, ratio = L / R
};
// ramus_height_mm (Co–Go), body_length_mm (Go–Me), gonial_angle_deg (Co–Go–Me),
// condyle_to_plane_mm, gonion_to_plane_mm; a measure is absent when its
// landmarks are missing.
std::map<std::string, Bilateral> bilateral_measures(const LandmarkSet& landmarks, const Plane& plane);

}  // namespace ms::asymmetry
