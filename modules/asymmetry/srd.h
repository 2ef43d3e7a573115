// Symmetry Robust Descriptor (METHOD.md §6): at a landmark p, the area-weighted
// histograms of the signed angle fields of the configurations that contain p,
// over geodesic rings around p. θ changes sign under reflection, so the SRD of
// a left landmark equals the bin-reversed SRD of its mirror twin on a
// symmetric mandible, while intrinsic descriptors cannot tell the twins apart.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "asymmetry/saf.h"
#include "core/types.h"

namespace ms::asymmetry {

struct SrdOptions {
  int rings = 4;               // geodesic rings around the landmark
  double ring_width_mm = 5.0;  // ring r covers [r w, (r + 1) w) of edge-graph geodesic distance
  int bins = 12;               // angle bins over (-π, π]
};

// One configuration's part of a descriptor: rings × bins, each ring normalised
// to sum 1 (all zero when no unmasked face falls in the ring).
struct SrdBlock {
  std::string configuration;
  bool mirrored = false;  // the field of σ(C) rather than C
  std::vector<double> histogram;
};

struct Srd {
  std::string landmark;
  std::vector<SrdBlock> blocks;  // one per field whose configuration contains the landmark
};

// A landmark against its mirror twin (itself for a midline landmark).
struct SrdTwin {
  std::string landmark, twin;
  double mirror_mismatch = -1;  // distance to the bin-reversed twin: 0 for local mirror symmetry
  double handedness = -1;       // distance to the twin as it is: how far the descriptor tells the twins apart
};

struct SrdResult {
  SrdOptions options;
  std::map<std::string, Srd> descriptors;
  std::vector<SrdTwin> twins;  // each bilateral pair once (left landmark first), then midline landmarks
};

// Descriptor of landmark `name` centred at `centre` (a point on the surface)
// from the fields kept by compute_saf (SafOptions::keep_fields).
Srd compute_srd(const Mesh& mesh, const std::string& name, const Vec3& centre, const std::vector<AngleField>& fields,
                const SrdOptions& options = {});

// Descriptors at every disk centre of a SAF run and the twin comparisons.
SrdResult compute_srds(const Mesh& mesh, const SafResult& saf, const SrdOptions& options = {});

// Mean over matched blocks and non-empty rings of the circular Wasserstein-1
// distance (radians) between ring histograms. as_mirror = false matches blocks
// of the same field (the same landmark in two scans); as_mirror = true matches
// each block of a with the block of the mirrored field in b (a landmark and its
// twin) and, when reverse_bins, compares with b's angles negated. -1 if no
// block matches.
double srd_distance(const Srd& a, const Srd& b, int bins, bool as_mirror = false, bool reverse_bins = false);

}  // namespace ms::asymmetry
