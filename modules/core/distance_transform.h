// Exact Euclidean distance transforms and the binary morphology built on
// them, for 0/1 voxel grids stored x-fastest. No dependencies: segmentation
// (ITK side) and surface (VTK side) share it.
//
// Cost is linear in the voxels whatever the distance or ball radius
// (Felzenszwalb-Huttenlocher lower envelope, separable over the three axes,
// OpenMP over lines), where a structuring-element filter is linear in the
// kernel's voxels too.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace ms {

using Dims3 = std::array<std::size_t, 3>;

// Value of a voxel with no feature anywhere in the grid.
constexpr float kNoFeature = 1e20f;

// Squared distance (in the units of spacing, squared) from every voxel to the
// nearest voxel where feature[i] != 0; kNoFeature when there is none.
// Distances up to max_sq are exact; larger ones come out larger than max_sq
// but not exact (a threshold at max_sq or below needs no more, and features
// that far are skipped: a morphology of radius r is much cheaper with r^2).
std::vector<float> squared_distance_transform(const std::uint8_t* feature, const Dims3& dims,
                                              const std::array<double, 3>& spacing, float max_sq = kNoFeature);

// Depth inside an object as ITK's signed Maurer distance map measures it:
// the distance (units of spacing) from each object voxel to the nearest voxel
// of the object's contour (object voxels with a background voxel among their
// 26 neighbours inside the grid: the grid's faces are not a contour); 0 for
// contour and background voxels. Depths up to max_depth are exact; deeper
// voxels come out deeper than max_depth but not exact (callers that only
// compare depths with thresholds up to max_depth pass it: the transform then
// looks only that far along each axis).
std::vector<float> depth_inside(const std::uint8_t* mask, const Dims3& dims, const std::array<double, 3>& spacing,
                                float max_depth = kNoFeature);

// Binary morphology with the ball ITK's BinaryBallStructuringElement builds
// for a per-axis radius r (voxel offsets o with sum (o_a / (r_a + 0.5))^2 <= 1;
// r = 1 is the 18-neighbourhood), with ITK's boundary conventions: outside the
// grid is background for a dilation and foreground for an erosion. In place
// on a 0/1 mask.
void dilate_ball(std::vector<std::uint8_t>& mask, const Dims3& dims, const std::array<int, 3>& radius);
void erode_ball(std::vector<std::uint8_t>& mask, const Dims3& dims, const std::array<int, 3>& radius);
// Erosion then dilation.
void open_ball(std::vector<std::uint8_t>& mask, const Dims3& dims, const std::array<int, 3>& radius);
// Dilation then erosion as if the grid were embedded in background (ITK's
// closing with SafeBorder): an object at the grid's edge is not eaten into.
void close_ball(std::vector<std::uint8_t>& mask, const Dims3& dims, const std::array<int, 3>& radius);

// Closing by a Euclidean ball of radius r in the units of spacing (the
// voxels within r of the mask, minus those within r of what lies farther
// than r from it). Within the grid only: pad the grid first to close up to
// its edges.
void close_euclidean(std::vector<std::uint8_t>& mask, const Dims3& dims, const std::array<double, 3>& spacing, double r);

}  // namespace ms
