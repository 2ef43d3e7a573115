// Test support: the OpenKBP head-and-neck CTs in ../shared/data/openkbp
// (sparse CSV, 128^3, HU + 1000, C-order (row, column, slice); slice 0 most
// superior, row 0 most anterior; column side unknown) placed in LPS with
// anterior and superior right: i = column (taken as +L), j = row (+P),
// k = slice (-S).
#pragma once

#include <string>

#include "core/types.h"

namespace ms::testing {

struct OpenKbpCase {
  Volume ct;     // HU
  Mask mandible; // clinical contour
};

// Throws std::runtime_error if the folder cannot be read.
OpenKbpCase load_openkbp(const std::string& dir);

// Dice overlap of two masks on the same grid.
double dice(const Mask& a, const Mask& b);

}  // namespace ms::testing
