// Mask -> closed, outward-oriented triangle mesh in LPS mm (VTK), and mesh
// writers. Thin first version: Gaussian-smoothed mask, flying edges at 0.5,
// quadric decimation, largest component, orientation check. Issue D adds CGAL
// repair and isotropic remeshing.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/types.h"

namespace ms::surface {

struct Options {
  double smoothing_sigma_mm = 0.6;  // Gaussian pre-smoothing of the binary mask
  std::size_t target_faces = 60000; // decimate above this many triangles (0 = never)
};

struct MeshStats {
  std::size_t vertices = 0, faces = 0;
  double area_mm2 = 0, volume_mm3 = 0;
  int genus = -1;        // from the Euler characteristic; -1 when not closed
  bool closed = false;   // every edge shared by exactly two faces
  bool manifold = false;
};

struct Result {
  Mesh mesh;
  MeshStats stats;
};

// Throws ms::Error(GeometryFailed) if the mask yields no surface.
Result mesh_from_mask(const Mask& mask, const Options& options = {});

// Topology and measures of a mesh (signed volume: positive when outward).
MeshStats measure(const Mesh& mesh);

// Per-vertex arrays written into the VTP (name -> one value per vertex).
using PointArrays = std::map<std::string, std::vector<double>>;
void write_vtp(const Mesh& mesh, const PointArrays& arrays, const std::string& path);
void write_stl(const Mesh& mesh, const std::string& path);  // binary
void write_ply(const Mesh& mesh, const std::string& path);  // binary
Mesh read_vtp(const std::string& path);

}  // namespace ms::surface
