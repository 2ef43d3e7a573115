// Convex hull of points in a plane (Andrew's monotone chain). Used where a
// definition is "the tangent of an outline": gonion in the landmark detector
// and in the phantom's ground truth.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

namespace ms {

// Indices of the hull's vertices, counter-clockwise (x right, y up), starting
// at the lowest-x (then lowest-y) point; collinear points on an edge are left
// out. Fewer than three distinct points: the distinct points, sorted.
std::vector<std::size_t> convex_hull_2d(const std::vector<std::array<double, 2>>& points);

}  // namespace ms
