// Mask -> closed, outward-oriented, isotropic triangle mesh in LPS mm, and
// mesh writers (docs/surface.md): Gaussian-smoothed mask, flying edges at 0.5
// (VTK), quadric decimation, then CGAL repair (soup repair, non-manifold
// vertices, holes, self-intersections), isotropic remeshing and outward
// orientation (repair.cpp).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/types.h"

namespace ms::surface {

struct Options {
  double smoothing_sigma_mm = 0.6;  // Gaussian pre-smoothing of the binary mask
  // Masks finer than this (mm) are contoured on a bin-averaged grid of at
  // most this spacing (integer bins per axis), with the Gaussian narrowed so
  // that bin and Gaussian together smooth by smoothing_sigma_mm; only bins
  // whose own blur stays within half the smoothing's variance are used, so a
  // near-zero sigma keeps the voxel boundary (0 = always full resolution;
  // docs/surface.md, "Fine masks").
  double max_contour_spacing_mm = 1.0;
  double close_handles_mm = 0;      // closing radius before meshing (0 = none)
  // When the surface has handles (genus > 0) and close_handles_mm is 0, mesh
  // again with a closing of 1, 2, then 3 mm (radii below the voxel size are
  // skipped) and keep the first genus-0 result; none reaching genus 0 keeps
  // the unclosed surface (docs/surface.md).
  bool close_handles_auto = false;
  // With a closing: keep only the closing's plugs, where it removed a handle
  // or filled a cavity, not its fill of creases and fissures (homotopic
  // thinning, core/topology.h). Auto closing tries this first at each radius.
  bool closing_plugs_only = false;
  // Sub-voxel placement: with a CT on the mask's grid, the contour follows
  // the CT's iso-level guide_level_hu where it crosses between a mask voxel
  // and a non-mask neighbour (partial volume), instead of the midpoint; the
  // surface's topology stays the mask's (docs/surface.md, "Sub-voxel
  // placement"). Null: the binary mask alone.
  const Volume* guide = nullptr;
  double guide_level_hu = 700.0;
  double guide_soft_hu = 40.0;  // soft tissue: the guide's span is level +- (level - soft)
  // Every vertex of the result lies within this many of the mask's finest
  // voxel spacing of the boundary of the mask as contoured (after any
  // closing): vertices the smoothing or remeshing carried farther, e.g. off
  // a cusp, are pulled back onto that shell (0 = never; docs/surface.md).
  double max_boundary_distance_voxels = 1.0;
  std::size_t target_faces = 60000; // decimate above this many triangles (0 = never)
  double target_edge_mm = 1.0;      // isotropic remeshing edge length (0 = no CGAL repair/remeshing)
  int remesh_iterations = 3;
};

struct RepairOptions {
  double target_edge_mm = 1.0;  // 0: repair only
  int remesh_iterations = 3;
};

struct RepairReport {
  std::size_t non_manifold_vertices = 0;     // split apart
  std::size_t components_removed = 0;        // small disconnected pieces dropped
  std::size_t holes_filled = 0;
  std::size_t self_intersections_before = 0; // intersecting face pairs found (then removed)
  std::size_t self_intersections_after = 0;  // left in the final mesh
  bool remeshed = false;
};

// CGAL repair and isotropic remeshing of a triangle mesh in place (LPS mm);
// the result is outward-oriented when closed.
RepairReport repair_and_remesh(Mesh& mesh, const RepairOptions& options = {});

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
  RepairReport repair;
  double closing_mm = 0;          // closing radius applied (0 = none)
  int genus_before_closing = -1;  // genus of the unclosed surface when auto closing ran
  bool closing_plugs_only = false;  // the closing was kept only where it changed the topology
  std::size_t vertices_pulled = 0;  // vertices pulled back to max_boundary_distance_voxels
  std::size_t voxels_joining = 0;   // voxels set to join pieces touching only diagonally (step 1)
  double largest_pull_mm = 0;       // the largest such move
};

// A mask and its mirror image along the grid's lateral axis give the same
// mesh reflected (the crop is meshed in a canonical orientation; docs/surface.md).
// Throws ms::Error(GeometryFailed) if the mask yields no surface.
Result mesh_from_mask(const Mask& mask, const Options& options = {});

// Topology and measures of a mesh (signed volume: positive when outward).
MeshStats measure(const Mesh& mesh);

// Binary closing of a mask by a ball of radius_mm (Euclidean, in mm, voxel
// centres): dilation = voxels within radius_mm of the mask, then erosion =
// voxels farther than radius_mm from every voxel outside the dilation (only
// voxels of the grid count). Two exact distance transforms, linear in the
// voxels whatever the radius. What --close-handles applies before meshing.
Mask closed(const Mask& mask, double radius_mm);

// Per-vertex arrays written into the VTP (name -> one value per vertex).
using PointArrays = std::map<std::string, std::vector<double>>;
void write_vtp(const Mesh& mesh, const PointArrays& arrays, const std::string& path);
void write_stl(const Mesh& mesh, const std::string& path);  // binary
void write_ply(const Mesh& mesh, const std::string& path);  // binary
Mesh read_vtp(const std::string& path);

}  // namespace ms::surface
