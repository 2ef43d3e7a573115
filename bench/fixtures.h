// Inputs of the kernel benchmarks, built once per process and cached: the
// same phantom and the same chain as the phantom tests
// (tests/reference/test_plane_phantoms.cpp): phantom::generate ->
// surface::mesh_from_mask(ground-truth mandible) -> landmarks::detect ->
// reference::fit. Only the stages' value-type headers are used here, so this
// file belongs to neither side of the ITK / Eigen split.
#pragma once

#include <cstddef>
#include <filesystem>

#include "core/types.h"
#include "landmarks/landmarks.h"
#include "phantom/phantom.h"
#include "reference/reference.h"
#include "surface/surface.h"

namespace ms::bench {

// The phantom every kernel runs on: head posed (yaw 8, pitch 6, roll -5 deg)
// so that the voxel surface is not trivially symmetric, left ramus +4 mm,
// default noise (15 HU) and PSF blur, field of view 150 x 140 x 130 mm as in
// the phantom tests, isotropic spacing_mm. Cached per spacing.
const phantom::Phantom& head_phantom(double spacing_mm);

// Grid size the phantom of that spacing has, without generating it.
std::size_t head_phantom_voxels(double spacing_mm);

// Ground-truth mandible of the 1 mm phantom meshed by the surface stage with
// the given isotropic remeshing edge (1 mm: the pipeline default, ~35k
// vertices; kEdgeFor50k: ~50k vertices), with its detected landmarks and the
// fitted symmetry plane / reference configuration. Cached per edge length.
struct MeshCase {
  surface::Result surface;
  landmarks::Result landmarks;
  reference::Result reference;
  const Mesh& mesh() const { return surface.mesh; }
};
const MeshCase& mandible_mesh(double edge_mm);

// A scratch folder for the writer kernels (created on first use, removed at exit).
const std::filesystem::path& scratch_dir();

constexpr double kEdgeDefault = 1.0;
constexpr double kEdgeFor50k = 0.84;  // measured: ~50k vertices on the 1 mm phantom

}  // namespace ms::bench
