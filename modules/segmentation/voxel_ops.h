// Voxel operations of the segmentation (docs/segmentation.md): hole filling,
// the marker-controlled watershed, and the resampling between the scan's grid
// and the grids the separation works on. Used by segmentation.cpp; declared
// here so that each can be tested on small hand-built grids.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/distance_transform.h"
#include "core/types.h"

namespace ms::segmentation {

// Hole filling (step 2): out = mask plus every component of its background
// that does not reach a face of the grid (an enclosed cavity). The
// background's components are fully connected (26) or face-connected (6):
// with fully_connected false a cavity leaks only through face contacts, so a
// thin shell whose voxels touch by edges or corners still encloses it.
// mask and out hold dims' voxel count (x fastest).
void fill_holes(const std::uint8_t* mask, const Dims3& dims, bool fully_connected, std::uint8_t* out);

// Marker-controlled watershed (step 5): priority flooding from the voxels
// where markers > 0 (their labels), face-connected, through the voxels where
// inside is set; levels quantised to 2^16 steps over [lo, hi]. A voxel takes
// the label of the flood that reaches it first (lowest level first, first in
// first out within a level); voxels not reached keep 0.
std::vector<unsigned> watershed(const std::vector<float>& level, const Geometry& g, float lo, float hi,
                                const std::vector<std::uint8_t>& inside, const std::vector<unsigned>& markers);

// Block averages over f[a] voxels per axis (the locate grid, "Locating the
// mandible first"): each coarse voxel is the mean of its block and sits at
// the block's centre; incomplete blocks at the far faces are dropped.
Volume bin_average(const Volume& ct, const std::array<unsigned, 3>& f);

// Trilinear interpolation onto a finer working grid ("Coarse scans"): axes
// coarser than max_spacing get that spacing over the same extent, from the
// same origin; the others are kept.
Volume interpolate_finer(const Volume& ct, double max_spacing);

// A mask on a finer grid brought back to grid g by majority: a voxel is set
// when more than half of the fine voxels within its footprint are.
Mask coarsen(const Mask& fine, const Geometry& g);

}  // namespace ms::segmentation
