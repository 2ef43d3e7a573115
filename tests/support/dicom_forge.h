// Test support: writes DICOM files with full control over every tag, the
// transfer syntax and enhanced multi-frame functional groups (GDCM), so tests
// can create the good and bad inputs real archives contain.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/types.h"

namespace ms::testing {

struct SliceSpec {
  unsigned rows = 24, cols = 28;
  Vec3 ipp{0, 0, 0};
  Vec3 row_dir{1, 0, 0}, col_dir{0, 1, 0};
  double spacing_i = 0.9, spacing_j = 0.8;  // along row_dir / col_dir
  double slope = 1, intercept = -1024;
  std::string modality = "CT";
  std::string sop_class = "1.2.840.10008.5.1.4.1.1.2";  // CT Image Storage
  std::string series_uid = "1.2.3.4.5.1", study_uid = "1.2.3.4.5", sop_uid;  // sop_uid empty: generated
  std::string image_type = "ORIGINAL\\PRIMARY\\AXIAL";
  std::string photometric = "MONOCHROME2";
  std::string description = "forged";
  int instance = 1;
  bool signed_pixels = false;
  unsigned bits_stored = 16;
  unsigned samples_per_pixel = 1;
  std::optional<int> padding;
  bool omit_pixel_data = false, omit_ipp = false, omit_iop = false, omit_spacing = false;
  std::size_t truncate_pixel_bytes = 0;  // drop this many bytes from the end of the pixel data
  // raw (explicit VR little endian), implicit, jpeg-lossless, jpeg2000, rle
  std::string transfer_syntax = "raw";
  std::vector<std::int32_t> stored;  // rows*cols*samples stored values; empty: zeros
};

void write_slice(const std::string& path, const SliceSpec& spec);

// Enhanced CT: one file, one frame per entry of ipps, stored values per frame.
struct EnhancedSpec {
  SliceSpec base;  // rows, cols, orientation, spacing, rescale, UIDs
  std::vector<Vec3> ipps;
  std::vector<std::vector<std::int32_t>> frames;
};
void write_enhanced(const std::string& path, const EnhancedSpec& spec);

// Stored value for an HU value with the spec's rescale.
std::int32_t stored_for(const SliceSpec& s, double hu);

// A series of n axial slices at z0 + k*dz, pixel HU from f(LPS position).
// Returns the slice specs written (file k is dir/prefix_kkk.dcm).
std::vector<SliceSpec> write_series(const std::string& dir, SliceSpec base, int n, double z0, double dz,
                                    const std::function<double(const Vec3&)>& hu, const std::string& prefix = "s");

std::string unique_uid();

// Raw bytes for hand-made (also malformed) files, explicit VR little endian:
// the 128-byte preamble + "DICM", and one element with the header its VR
// calls for (long VRs: 2 reserved bytes + 32-bit length). declared_length
// overrides the length written in the header (the value stays as given).
std::string preamble();
std::string element(std::uint16_t group, std::uint16_t elem, const char* vr, const std::string& value,
                    std::optional<std::uint32_t> declared_length = std::nullopt);

}  // namespace ms::testing
