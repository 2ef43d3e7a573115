// Digital topology on 0/1 voxel grids (x fastest): simple points and the
// handle plugs of a closing. No dependencies; the surface stage uses it to
// close only the handles of a mask (docs/surface.md, "Handles").
//
// Connectivity is (6, 26): an object is 6-connected (face neighbours), the
// background 26-connected. It is the strict pair for the object: a sheet of
// object voxels that blocks every 26-path of the background has no pinholes
// along edges or corners, so a smoothed-and-contoured surface sees it closed.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/distance_transform.h"

namespace ms {

// Whether the object voxel or background voxel at (i, j, k) is simple: moving
// it to the other side changes no topology, (6, 26) (Bertrand & Malandain
// 1994: one 6-component of the object in its 18-neighbourhood 6-adjacent to
// it, one 26-component of the background in its 26-neighbourhood). Outside
// the grid counts as background. The voxel's own value is ignored.
bool is_simple_point(const std::uint8_t* mask, const Dims3& dims, std::size_t i, std::size_t j, std::size_t k);

// The part of a closing that changes topology. `closed` must be a closing of
// `original` by a ball of radius_mm (every voxel it adds lies within
// radius_mm of `original`); every voxel closed but not original that can be
// given back to the background without changing the topology of `closed` is
// given back, those farthest from `original` first (homotopic thinning), so
// what is left are thin plugs where the closing removed a handle or filled a
// cavity, at the tunnel's narrowest place, and nothing where it filled a
// crease. The plugs are then thickened by the removed voxels within
// thicken_mm of them that are simple to add back (a one-voxel sheet would not
// survive smoothing; the topology stays the closing's). In place on
// `closed`; returns the number of added voxels kept. Cost follows the added
// voxels, not the grid (their depths are searched in a ball around each);
// outside the grid counts as background.
std::size_t keep_closing_plugs(std::vector<std::uint8_t>& closed, const std::vector<std::uint8_t>& original,
                               const Dims3& dims, const std::array<double, 3>& spacing, double radius_mm,
                               double thicken_mm);

}  // namespace ms
