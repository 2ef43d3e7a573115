// Checks made on volume files (NIfTI, NRRD, MetaImage) before any library
// reads their voxels: the memory budget, the data files a detached header
// names (inside the header's folder, regular files), that the data really holds
// what the header declares (raw: byte for byte; gzip/zlib: by inflating the
// stream with constant memory), NIfTI datatypes, extra dimensions and
// orientation codes. No ITK here. Policies and limits: docs/ingest.md.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ms::io::checks {

// Geometry limits (DICOM and volume files), see docs/ingest.md "Geometry".
// A patient coordinate beyond 10 m from the scanner's origin is not a scan
// (an x of 1e300 mm crashed the mesh stage's exact arithmetic: SIGFPE).
constexpr double kMaxPositionMm = 1e4;
// Voxel and pixel sizes: 1 micrometre (below micro-CT's finest) to 10 cm (ten
// times the thickest clinical CT slice); 1e30 mm passed as "no bone" before.
constexpr double kMinSpacingMm = 1e-3;
constexpr double kMaxSpacingMm = 100.0;
// Direction cosines: unit columns and |det| within this of 1 (0.6 degree).
constexpr double kDirectionTolerance = 1e-2;
// Files one detached header may name (a list or a %d pattern): one per slice
// at most, and no CT has more than a few thousand slices.
constexpr std::uint64_t kMaxDataFiles = 65536;

// The budget to use: `requested`, or ms::default_memory_budget_bytes() when 0.
std::uint64_t effective_budget(std::uint64_t requested);

// Throws ms::Error(InputInvalid) when a run on `voxels` voxels would need more
// than `budget` bytes (0: no limit). `what` says who declares them
// ("NIfTI header", "DICOM series").
void check_budget(const std::string& path, const std::string& what, std::uint64_t voxels, std::uint64_t budget);

// Throws ms::Error(InputInvalid) unless `file` (after symlinks) is a regular
// file: a FIFO blocks forever, /dev/zero never ends. `path` names the input.
void require_regular_file(const std::string& file, const std::string& path, const std::string& role);

// Where a NRRD or MetaImage header's voxels are.
struct DataLayout {
  bool known = false;            // false: not parsed (left to the reader; the budget still holds)
  std::string encoding;          // "raw", "gzip" (gzip or zlib stream) or "other"
  bool attached = false;         // the voxels follow the header in the same file
  std::uint64_t offset = 0;      // attached: where they start
  std::int64_t skip = 0;         // NRRD "byte skip" / MetaImage HeaderSize (-1: data at the end)
  std::vector<std::string> files;  // detached: the data files, resolved
};

// Parses the header's data-file field (single name, LIST, %d pattern) and its
// encoding; every data file must resolve (std::filesystem::weakly_canonical,
// after symlinks) inside the header's folder unless allow_external, and be a
// regular file. Throws ms::Error naming the header and the data file.
DataLayout data_layout(const std::string& header, const std::string& kind, bool allow_external);

// The data must hold `declared` bytes of voxels: raw data byte for byte (a
// short file made the reader allocate everything first), gzip/zlib streams by
// inflating them with constant memory, stopping at `declared`.
void check_data_holds(const std::string& header, const std::string& kind, const DataLayout& layout, std::uint64_t declared);

// NIfTI-1 header checks before its payload is read: scalar datatypes only, no
// 4th or higher dimension > 1, and the budget. Does nothing for headers that
// are not NIfTI-1 (check_nifti_payload refuses or defers those).
void check_nifti_header(const std::string& path, std::uint64_t budget);

// NIfTI orientation codes: Consistent (one of qform/sform, or both agreeing
// within 1 degree per axis and 1 voxel of origin), NotCoded (qform_code =
// sform_code = 0: left/right unknown) or Disagree (why says how).
enum class NiftiOrientation { NotNifti1, Consistent, NotCoded, Disagree };
NiftiOrientation nifti_orientation(const std::string& path, std::string* why);

// Fields of a binary header (NIfTI) at byte `off`, byte-swapped when `swap`.
std::int16_t header_i16(const unsigned char* h, int off, bool swap);
std::int32_t header_i32(const unsigned char* h, int off, bool swap);
float header_f32(const unsigned char* h, int off, bool swap);

}  // namespace ms::io::checks
