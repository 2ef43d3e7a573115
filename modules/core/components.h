// Connected components of a 0/1 voxel grid (x fastest), face-connected
// (6-neighbourhood) or fully connected (26). No dependencies.
//
// The labels are those of ITK's ConnectedComponentImageFilter (FullyConnected
// off or on) followed by RelabelComponentImageFilter with a minimum object size:
// components of at least min_voxels voxels are numbered 1..n by decreasing
// size, ties by the raster position of their first voxel; smaller ones are 0.
// It does the same in one union-find pass and one relabelling pass, without
// ITK's run-length tables and intermediate images (5x faster on a 16 M-voxel
// bone crop; docs/segmentation.md, "Speed").
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/distance_transform.h"

namespace ms {

struct Components {
  std::size_t count = 0;           // n: labels 1..n
  std::vector<std::size_t> sizes;  // sizes[l], voxels of label l (sizes[0] = 0)
};

// Labels the set voxels of mask into out (dims' voxel count; every voxel is
// written). min_voxels 0 keeps every component.
Components label_components(const std::uint8_t* mask, const Dims3& dims, bool fully_connected, std::size_t min_voxels,
                            std::uint32_t* out);

// Joins the pieces of mask that touch only at a voxel edge or corner, so that
// its face-connected (6) components are its fully connected (26) ones: the
// pieces an iso-surface at 0.5 keeps apart are those the mask itself keeps
// apart. A bone one voxel thin (a condylar neck at ~4.5 mm voxels) is often
// continuous only diagonally. Each join sets one background voxel that is a
// face neighbour of both pieces (an edge contact); a corner contact first
// gains the voxel that makes it an edge contact. Of the voxels that would
// join the same pieces, the one with the most set voxels among its 26
// neighbours is used (the first in storage order on a tie; one that also
// touches a third piece only when no other joins the two), and only one join
// per pair of pieces, so no join closes a loop between pieces. Only pieces
// that touch are joined. Returns the number of voxels set.
std::size_t join_diagonal_contacts(std::uint8_t* mask, const Dims3& dims);

}  // namespace ms
