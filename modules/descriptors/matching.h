// Descriptor matching and robust rigid registration from correspondences, and
// its use in pre/post comparison: moving landmarks from one scan of a mandible
// to another by local ISI matching + RANSAC + ICP (docs/descriptors.md).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/types.h"
#include "reference/reference.h"

namespace ms::descriptors {

// The k nearest rows of base (Euclidean) for every row of query; rows have
// length len. Result: query-major, k entries each (index -1 and +inf distance
// where base has fewer rows).
struct Neighbour {
  int index = -1;
  float distance = 0;
};
std::vector<Neighbour> nearest(const std::vector<float>& query, const std::vector<float>& base, int len, int k = 1);

struct RansacResult {
  reference::RigidTransform transform;  // src -> dst
  std::vector<int> inliers;             // indices into the correspondence list
  double rms_mm = 0;                    // over the inliers, after refitting on them
};
// RANSAC over minimal 3-point samples (Kabsch), inlier when the mapped source
// lies within inlier_mm of its target; the best sample's inliers are refitted.
// Deterministic for a seed. Fewer than 3 correspondences: identity, no inliers.
RansacResult ransac_rigid(const std::vector<Vec3>& src, const std::vector<Vec3>& dst, double inlier_mm, int iterations,
                          std::uint64_t seed);

struct TransferOptions {
  double patch_radius_mm = 25;   // the neighbourhood of a landmark that is registered
  int patch_features = 300;      // ISI keypoints sampled in that patch
  int target_features = 8000;    // ISI keypoints sampled once on the whole target
  double search_radius_mm = 40;  // candidates on the target: within this of the globally aligned landmark
  double inlier_mm = 0;          // RANSAC inlier distance; 0 = 3 x the coarser mesh resolution
  int ransac_iterations = 3000;
  double min_overlap = 0.6;      // registration trusted when this fraction of the patch lies within 1 mm of the target
  double agree_mm = 3;           // a detected landmark farther than this from the transferred one is not trusted
  std::uint64_t seed = 1;
};

struct LandmarkTransfer {
  std::string name;
  bool detected = false;     // the target scan's own detector found it
  Vec3 detected_point{0, 0, 0};
  bool registered = false;   // the local registration was trusted (overlap, inliers)
  Vec3 transferred{0, 0, 0}; // source landmark mapped by the local registration, on the target surface
  double overlap = 0;        // fraction of the source patch within 1 mm of the target after registration
  double rms_mm = 0;         // ICP residual of the patch
  int inliers = 0;           // RANSAC inlier correspondences
  double disagreement_mm = -1;  // |detected - transferred| when both exist
  bool used = false;         // the transferred point replaces (or stands in for) the detected one
  std::string reason;        // one line: why used or not
};

// For every landmark of source: registers its neighbourhood on source to
// target (ISI keypoints, two nearest descriptors each, RANSAC, then
// point-to-plane ICP of the patch) starting the candidate search from
// global (source -> target, e.g. the compare alignment inverted). The
// transferred landmark is used when the registration is trusted and the
// target's detection is missing or disagrees by more than agree_mm.
std::vector<LandmarkTransfer> transfer_landmarks(const Mesh& source, const LandmarkSet& source_landmarks, const Mesh& target,
                                                 const LandmarkSet& target_landmarks,
                                                 const reference::RigidTransform& global,
                                                 const TransferOptions& options = {});

}  // namespace ms::descriptors
