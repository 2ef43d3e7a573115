// DICOM outputs of a run (docs/pacs.md), written with DCMTK into the source
// study: a Segmentation (SEG) of the mandible mask on the CT's frames, a
// Comprehensive 3D SR measurement report (TID 1500) holding results.json's
// numbers, and the report as an Encapsulated PDF. Each object is a new series
// with new UIDs that references the source CT series and its instances; the
// patient and study modules are copied from the CT, or emptied under
// --deidentify (PS3.15 Basic Profile with the Retain UIDs Option, so the
// objects still point at the CT they were derived from).
//
// No DCMTK type appears here: the module's users see value types only.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/json_text.h"
#include "core/types.h"

namespace ms::dicomout {

// The patient and study attributes every output carries, read once from a
// file of the source series. Tags are (group << 16 | element).
struct StudyContext {
  std::vector<std::pair<std::uint32_t, std::string>> attributes;  // patient + general study modules
  std::string specific_character_set;                             // (0008,0005) of the source, copied
  bool deidentified = false;
  std::string tool_version;  // "0.1.0": SoftwareVersions of every output
};

// Reads the patient and general study modules of source.first_file (header
// only). With deidentify, identifying values are emptied or removed and the
// de-identification attributes are set (docs/pacs.md, "De-identification").
// Throws ms::Error(InputInvalid) if the file cannot be read.
StudyContext read_study_context(const DicomSource& source, bool deidentify, const std::string& tool_version);

// The source with a Frame of Reference all outputs can share: the CT's, or
// for a CT without FrameOfReferenceUID (0020,0052) a new UID, which *note
// then reports (the SEG needs one; the SR's points use the same).
DicomSource ensure_frame_of_reference(DicomSource source, std::string* note);

// One object written.
struct Written {
  std::string path;                 // file written
  std::string sop_class_uid, sop_instance_uid, series_instance_uid;
  std::string what;                 // "SEG", "SR", "PDF"
};

// Identity of the SEG the SR's measurements point at.
struct SegmentRef {
  std::string sop_class_uid, sop_instance_uid;
  unsigned segment_number = 1;
  std::string series_instance_uid;  // the SEG's series: the SR lists the SEG in its evidence
};

// DICOM SEG (binary) of the mask on the source frames' pixel grids: one frame
// per source frame the mask touches, nearest-neighbour in LPS world
// coordinates, same Frame of Reference, per-frame plane position, shared
// orientation and pixel measures from the CT, derivation references to the
// source instances. Segment 1: SCT 91609006 "Mandible", algorithm AUTOMATIC
// (or MANUAL for --mask), named MandiSym <version>.
Written write_seg(const Mask& mask, const DicomSource& source, const StudyContext& study, bool mask_from_user,
                  const std::string& path);

// Comprehensive 3D SR following TID 1500 with the numbers of results (the
// results.json document of the same run): scores, mirror distances,
// bilateral measures, menton deviation, landmarks (SCOORD3D in the source
// Frame of Reference) and QC status; every measurement group references the
// SEG segment (docs/pacs.md, "Measurement report").
Written write_sr(const Json& results, const DicomSource& source, const StudyContext& study, const SegmentRef& seg,
                 const std::string& path);

// report.pdf: the report's headline, QC, scores, bilateral table and key
// views (PNG files) composed with cairo; written to pdf_path.
void write_report_pdf(const Json& results, const std::vector<std::string>& view_pngs, const std::string& pdf_path);

// Encapsulated PDF Storage object holding the file at pdf_path.
Written write_encapsulated_pdf(const std::string& pdf_path, const DicomSource& source, const StudyContext& study,
                               const std::string& path);

}  // namespace ms::dicomout
