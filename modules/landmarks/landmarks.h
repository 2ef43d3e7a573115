// Anatomical landmarks on the mandible surface (METHOD.md §2).
// Thin first version: extreme vertices along LPS directions, split into patient
// left/right at the centroid. It assumes a roughly standard head pose; issue D
// replaces it with geodesic extreme points and pose-robust labelling.
#pragma once

#include <string>
#include <vector>

#include "core/types.h"

namespace ms::landmarks {

struct Result {
  LandmarkSet landmarks;       // LPS mm; missing landmarks are absent
  std::vector<std::string> missing;
  std::vector<std::string> warnings;
  std::string method;
};

Result detect(const Mesh& mesh);

}  // namespace ms::landmarks
