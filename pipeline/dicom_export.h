// `run --dicom`: the run's DICOM objects (docs/pacs.md) written into the
// staging folder's dicom/, and report.pdf beside report.html.
#pragma once

#include <string>
#include <vector>

#include "core/json_text.h"
#include "core/types.h"

namespace ms::pipeline {

struct DicomExport {
  const DicomSource* source = nullptr;  // null: the input was not DICOM (no dicom/ objects)
  bool deidentify = false;
  bool mask_from_user = false;  // --mask: the SEG's algorithm type is MANUAL
  std::string tool_version;
};

// report.pdf (always) and, with a source, dicom/seg.dcm, dicom/sr.dcm and
// dicom/report.dcm. Returns one line per object for the log.
std::vector<std::string> write_pdf_and_dicom(const std::string& staging_dir, const Json& results, const Mask& mask,
                                             const std::vector<std::string>& view_pngs, const DicomExport& e);

}  // namespace ms::pipeline
