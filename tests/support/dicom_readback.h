// Reading MandiSym's DICOM outputs back in tests, with plain dcmdata (not
// the classes that wrote them).
#pragma once

#include <string>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include "core/types.h"

namespace ms::test {

// The first item of `inner` inside item `index` of `seq` (a test failure when absent).
DcmItem& nested(DcmItem& item, const DcmTagKey& seq, unsigned index, const DcmTagKey& inner);

struct SegComparison {
  std::size_t frames = 0, set_pixels = 0, mismatches = 0;
};

// Every pixel of every frame of a binary SEG file against the mask at the
// pixel's LPS position (nearest voxel).
SegComparison compare_seg_with_mask(const std::string& seg_file, const ms::Mask& mask);

// "" when every NUM value of the SR file equals a number of the results.json
// file (to DS precision) and every SCOORD3D point a landmark (to FL
// precision); otherwise the values that match nothing, one per line.
// At least kMinSrNumbers NUM items must be present.
constexpr std::size_t kMinSrNumbers = 10;
std::string sr_numbers_mismatching_results(const std::string& sr_file, const std::string& results_json);

}  // namespace ms::test
