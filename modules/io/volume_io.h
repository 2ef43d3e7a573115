// Ingest and volume/mask writing (ITK + GDCM). Everything returned is in HU and
// patient LPS millimetres; see METHOD.md §0.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/array_order.h"
#include "core/types.h"

namespace ms::io {

struct ReadOptions {
  // Added to every voxel after the file's own rescale. Use for volume formats
  // stored as HU + 1024 (e.g. --hu-offset -1024). DICOM is rescaled by its own
  // RescaleSlope/Intercept and normally needs 0.
  double hu_offset = 0.0;
  // Pick this SeriesInstanceUID when a folder holds several series (empty:
  // the series with the most slices among CT series).
  std::string series_uid;
  // Volume files only: 3 letters naming where the i, j, k axes point (L/R,
  // P/A, S/I), replacing the file's direction (for files without anatomical
  // orientation). Empty: keep the file's.
  std::string orientation;
  // Memory budget in bytes for the whole run (docs/ingest.md, "Memory
  // budget"): every declared image size is checked against it before anything
  // is decoded or allocated (estimated peak = voxels x 4 B x
  // ms::kPipelinePeakFactor). 0: ms::default_memory_budget_bytes() (a
  // fraction of this machine's memory, cgroup limit or RLIMIT_AS). The CLI's
  // --max-memory SIZE goes here through ms::parse_memory_size.
  std::uint64_t max_memory_bytes = 0;
  // NRRD "data file:" / MetaImage "ElementDataFile" may name files outside
  // the header's folder (after symlinks). Default: refused (exit 4).
  bool allow_external_data_files = false;
};

struct LoadedScan {
  Volume volume;  // in the canonical array order (core/array_order.h)
  ScanInfo info;
  std::optional<DicomSource> dicom;  // the series read, when the input was DICOM
  AxisReorder stored_order;          // what brought the stored array order to the canonical one
};

// Reads a DICOM folder (searched recursively) or a volume file (.nii, .nii.gz,
// .nrrd, .nhdr, .mha, .mhd). Throws ms::Error (InputNotFound / InputInvalid)
// with a one-line message naming the path.
LoadedScan read_scan(const std::string& path, const ReadOptions& options = {});

// Writes a float32 HU volume (NIfTI, NRRD or MetaImage by extension).
void write_volume(const Volume& volume, const std::string& path);

// Writes a uint8 mask as NIfTI (.nii or .nii.gz) on its own grid.
void write_mask(const Mask& mask, const std::string& path);
// The mask (on a scan's canonical grid) in the array order the scan was
// stored in (LoadedScan::stored_order): the same voxels, indexed as the input.
Mask in_stored_order(const Mask& mask, const AxisReorder& stored_order);
// Reads a mask (any ITK-readable format); voxels != 0 become 1.
Mask read_mask(const std::string& path);
// Reads an integer label map (any ITK-readable format, values rounded).
LabelMap read_label_map(const std::string& path);

// Identity written into every slice of a generated series.
struct DicomSeriesSpec {
  std::string patient_name = "ANONYMOUS^PHANTOM";
  std::string patient_id = "PHANTOM";
  std::string study_description = "MandiSym phantom";
  std::string series_description = "MandiSym synthetic head CT";
  std::string study_date = "20260101";
  // StudyTime, SeriesTime, AcquisitionTime, ContentTime and the instance
  // creation time of every slice (one value per series: a converter such as
  // dcm2niix splits a series whose slices differ in them).
  std::string study_time = "120000";
  std::string manufacturer = "MandiSym";
  std::string model = "phantom";
  std::string kernel = "STANDARD";
  std::string file_prefix = "IM";
  // Empty: fresh UIDs are generated (GDCM UID generator).
  std::string study_uid;
  std::string series_uid;
  // Transfer syntax: "raw" (explicit little endian), "jpeg-lossless" (process 14) or
  // "jpeg2000" (lossless). ITK 5.2 cannot write RLE.
  std::string compression = "raw";
};

// Writes a CT Image Storage series, one file per slice along the volume's k
// axis, HU stored as uint16 with RescaleIntercept -1024 and slope 1, with
// ImagePositionPatient/ImageOrientationPatient/PixelSpacing from the geometry.
// Returns the SeriesInstanceUID written.
std::string write_dicom_series(const Volume& ct, const DicomSeriesSpec& spec, const std::string& dir);

}  // namespace ms::io
