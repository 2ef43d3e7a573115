// DICOM series discovery, geometry analysis and volume assembly (GDCM).
//
// Policies (docs/ingest.md):
// - Files are grouped by SeriesInstanceUID; a UID holding images of different
//   orientation or matrix size is split into sub-stacks.
// - Slices are ordered by the position of ImagePositionPatient along the slice
//   normal (row x column direction), never by file name or InstanceNumber.
// - Gantry tilt: resampled onto an orthogonal grid (warning).
// - Missing slices (gaps up to 3 x the nominal spacing) and non-uniform
//   spacing: resampled onto the nominal spacing by linear interpolation
//   (warning); larger gaps are refused.
// - Duplicate positions: exact duplicates are dropped (warning); different
//   images at one position are refused.
// - HU = stored x RescaleSlope + RescaleIntercept per slice; PixelPaddingValue
//   (and range) and values below -1024 HU become air (-1024); MONOCHROME1 is a
//   display convention and does not change HU.
// - Enhanced (multi-frame) CT: per-frame functional groups give position,
//   orientation, spacing and rescale of each frame.
#pragma once

#include <set>
#include <string>
#include <vector>

#include "core/types.h"

namespace ms::io::dicom {

struct Frame {
  std::string file;
  unsigned frame = 0;  // index within a multi-frame file
  Vec3 ipp{0, 0, 0};
  bool has_ipp = false;
  Vec3 row_dir{1, 0, 0}, col_dir{0, 1, 0};  // IOP: direction of a row (i), of a column (j)
  bool has_iop = false;
  double spacing_i = 0, spacing_j = 0;  // mm along row_dir / col_dir (PixelSpacing[1], [0])
  unsigned rows = 0, cols = 0;
  double slope = 1, intercept = 0;
  bool has_slope = false, has_intercept = false;  // the tag is present (value valid or not)
  std::string bad_value;  // "RescaleSlope 'inf'": a present tag whose value is unusable
  int instance = 0;
  std::string sop_instance_uid;  // of the file holding the frame
};

struct Series {
  std::string uid, study_uid, modality, description, image_type, study_date, manufacturer, model, kernel;
  std::string photometric, transfer_syntax, sop_class;
  std::string frame_of_reference_uid;
  std::string label;  // uid, or uid#n for a sub-stack
  unsigned bits_allocated = 16, bits_stored = 16, pixel_representation = 0, samples_per_pixel = 1;
  bool has_padding = false, has_padding_limit = false;
  double padding = 0, padding_limit = 0;
  bool missing_pixel_data = false;  // some file of the series has none
  std::string missing_pixel_data_file;
  std::vector<Frame> frames;
  std::set<std::string> files;
};

struct ScanResult {
  std::string path;
  std::vector<Series> series;
  std::size_t files_seen = 0;        // regular files looked at
  std::size_t dicom_files = 0;       // parsed as DICOM
  std::size_t non_image_files = 0;   // DICOM without an image (SR, RTSTRUCT, ...)
  std::size_t unreadable_files = 0;  // could not be opened (permissions)
  std::size_t special_files = 0;     // entries that are not regular files (FIFOs, devices, sockets): skipped
  std::string first_special;
  std::string first_unreadable;
  std::string first_non_dicom;       // for messages
};

struct Layout {
  bool usable = false;
  std::string problem;  // one line when not usable
  std::vector<std::string> warnings;
  std::vector<std::size_t> order;                       // frame indices sorted along the normal
  std::vector<std::vector<std::size_t>> duplicates;     // extra frames at an already used position
  Vec3 normal{0, 0, 1};
  double nominal_spacing = 0;  // along the normal
  double extent_mm = 0;        // covered along the normal
  double tilt_deg = 0;
  double max_gap = 0;
  bool resample = false;       // tilt, gaps or non-uniform spacing
  std::string orientation;     // axial, coronal, sagittal or oblique
};

// Scans a folder (recursively, any file names) or a single file. Never throws
// for unreadable or non-DICOM files; they are counted.
ScanResult scan(const std::string& path);

// Whether a file's structure can be handed to GDCM (which asserts, or
// allocates whatever a length declares, on some malformed files): a complete
// file meta group, a data-set start where there is no preamble, and every
// declared length up to the pixel data within the file. scan() skips files
// that fail it as not DICOM.
bool safe_to_parse(const std::string& file);

// Geometry checks of one series (no pixel data read).
Layout analyse(const Series& series);

// Index of the series to use: CT, not a localizer, usable geometry, largest
// coverage along the normal, then finest voxels, then most slices. -1 if none;
// why explains the choice or the refusal in one line.
int choose(const ScanResult& scan, const std::vector<Layout>& layouts, std::string* why);

// Decodes the pixel data (any transfer syntax GDCM supports), applies rescale
// and padding, and builds the volume on an orthogonal grid (resampling where
// the layout says so). Throws ms::Error(InputInvalid) naming the file on
// corrupt or missing pixel data.
// memory_budget (bytes, 0: none): a resampled grid whose run would exceed it
// is refused before it is allocated (docs/ingest.md, "Memory budget").
Volume assemble(const Series& series, const Layout& layout, std::vector<std::string>& warnings,
                std::uint64_t memory_budget = 0);

// The series as the DICOM writers reference it: its UIDs and the frames in
// the layout's order (duplicates left out), each with its instance and geometry.
DicomSource source_of(const Series& series, const Layout& layout);

}  // namespace ms::io::dicom
