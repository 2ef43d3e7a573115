#include "pipeline/dicom_export.h"

#include <filesystem>

#include "core/error.h"
#include "dicomout/dicomout.h"

namespace fs = std::filesystem;

namespace ms::pipeline {

std::vector<std::string> write_pdf_and_dicom(const std::string& staging_dir, const Json& results, const Mask& mask,
                                             const std::vector<std::string>& view_pngs, const DicomExport& e) {
  const fs::path dir(staging_dir);
  dicomout::write_report_pdf(results, view_pngs, (dir / "report.pdf").string());
  if (!e.source) return {};
  std::error_code ec;
  fs::create_directories(dir / "dicom", ec);
  if (ec) throw Error(ExitCode::OutputFailed, (dir / "dicom").string() + ": cannot create: " + ec.message());
  std::vector<std::string> lines;
  std::string note;
  const DicomSource source = dicomout::ensure_frame_of_reference(*e.source, &note);
  if (!note.empty()) lines.push_back("dicom: " + note);
  const dicomout::StudyContext study = dicomout::read_study_context(source, e.deidentify, e.tool_version);
  std::vector<dicomout::Written> written;
  written.push_back(dicomout::write_seg(mask, source, study, e.mask_from_user, (dir / "dicom" / "seg.dcm").string()));
  const dicomout::SegmentRef seg{written[0].sop_class_uid, written[0].sop_instance_uid, 1, written[0].series_instance_uid};
  written.push_back(dicomout::write_sr(results, source, study, seg, (dir / "dicom" / "sr.dcm").string()));
  written.push_back(dicomout::write_encapsulated_pdf((dir / "report.pdf").string(), source, study,
                                                     (dir / "dicom" / "report.dcm").string()));
  for (const auto& w : written)
    lines.push_back("dicom: " + w.what + " " + fs::path(w.path).filename().string() + " SOPInstanceUID " + w.sop_instance_uid);
  return lines;
}

}  // namespace ms::pipeline
