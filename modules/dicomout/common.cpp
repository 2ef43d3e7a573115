#include "dicomout/common.h"

#include <cstdlib>
#include <ctime>
#include <filesystem>

#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/oflog/oflog.h>

#include "core/error.h"

namespace ms::dicomout {

namespace {

// What a de-identified output keeps of each copied attribute (PS3.15 Table
// E.1-1, Basic Profile with the Retain UIDs Option): 'U' kept (a UID), 'Z'
// present and empty, 'X' removed. required: Type 1 or 2 in the Patient or
// General Study module (PS3.3 C.7.1.1, C.7.2.1), so written, empty when the
// CT lacks it.
struct Copied {
  DcmTagKey tag;
  char deidentified;
  bool required;
};
const Copied kCopied[] = {
    // Patient module
    {DCM_PatientName, 'Z', true},
    {DCM_PatientID, 'Z', true},
    {DCM_IssuerOfPatientID, 'X', false},
    {DCM_PatientBirthDate, 'Z', true},
    {DCM_PatientSex, 'Z', true},
    {DCM_PatientAge, 'X', false},
    // General study module
    {DCM_StudyInstanceUID, 'U', true},
    {DCM_StudyDate, 'Z', true},
    {DCM_StudyTime, 'Z', true},
    {DCM_ReferringPhysicianName, 'Z', true},
    {DCM_StudyID, 'Z', true},
    {DCM_AccessionNumber, 'Z', true},
    {DCM_StudyDescription, 'X', false},
};

std::uint32_t key_of(const DcmTagKey& t) { return (static_cast<std::uint32_t>(t.getGroup()) << 16) | t.getElement(); }

std::string now(const char* format) {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  localtime_r(&t, &tm);
  char b[32];
  std::strftime(b, sizeof b, format, &tm);
  return b;
}

}  // namespace

void check(const OFCondition& cond, const std::string& context) {
  if (cond.bad()) throw Error(ExitCode::Internal, "DICOM output: " + context + ": " + cond.text());
}

void quiet_dcmtk() {
  static const bool once = [] {
    if (!std::getenv("MANDISYM_DCMTK_LOG")) OFLog::configure(OFLogger::FATAL_LOG_LEVEL);  // conditions are reported through check()
    return true;
  }();
  (void)once;
}

std::string new_uid() {
  char uid[100];
  dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT);
  return uid;
}

StudyContext read_study_context(const DicomSource& source, bool deidentify, const std::string& tool_version) {
  quiet_dcmtk();
  DcmFileFormat ff;
  const OFCondition c = ff.loadFileUntilTag(source.first_file.c_str(), EXS_Unknown, EGL_noChange, DCM_MaxReadLength, ERM_autoDetect,
                                            DCM_PixelData);
  if (c.bad()) throw Error(ExitCode::InputInvalid, source.first_file + ": cannot read its header for the DICOM outputs: " + c.text());
  DcmDataset& ds = *ff.getDataset();
  StudyContext ctx;
  ctx.deidentified = deidentify;
  ctx.tool_version = tool_version;
  OFString v;
  if (ds.findAndGetOFStringArray(DCM_SpecificCharacterSet, v).good()) ctx.specific_character_set = v.c_str();
  for (const Copied& a : kCopied) {
    v.clear();
    const bool present = ds.findAndGetOFStringArray(a.tag, v).good();
    if (deidentify && a.deidentified == 'X') continue;
    if (deidentify && a.deidentified == 'Z') v.clear();
    if (present || a.required) ctx.attributes.emplace_back(key_of(a.tag), v.c_str());
  }
  return ctx;
}

DicomSource ensure_frame_of_reference(DicomSource source, std::string* note) {
  if (!source.frame_of_reference_uid.empty()) return source;
  source.frame_of_reference_uid = new_uid();
  if (note) *note = "the CT has no FrameOfReferenceUID: the SEG and the SR share a new one (" + source.frame_of_reference_uid + ")";
  return source;
}

void apply_study_context(DcmItem& item, const StudyContext& study) {
  if (!study.specific_character_set.empty())
    check(item.putAndInsertOFStringArray(DCM_SpecificCharacterSet, study.specific_character_set.c_str()), "SpecificCharacterSet");
  for (const Copied& a : kCopied) item.findAndDeleteElement(a.tag);
  for (const auto& [key, value] : study.attributes) {
    const DcmTagKey tag(static_cast<Uint16>(key >> 16), static_cast<Uint16>(key & 0xffff));
    check(item.putAndInsertOFStringArray(tag, value.c_str()), DcmTag(tag).getTagName());
  }
  if (!study.deidentified) return;
  check(item.putAndInsertString(DCM_PatientIdentityRemoved, "YES"), "PatientIdentityRemoved");
  check(item.putAndInsertString(DCM_DeidentificationMethod, "MandiSym --deidentify: PS3.15 Basic Profile, Retain UIDs"),
        "DeidentificationMethod");
  item.findAndDeleteElement(DCM_DeidentificationMethodCodeSequence);
  const char* codes[][2] = {{"113100", "Basic Application Confidentiality Profile"}, {"113110", "Retain UIDs Option"}};
  for (const auto& code : codes) {
    DcmItem* it = nullptr;
    check(item.findOrCreateSequenceItem(DCM_DeidentificationMethodCodeSequence, it, -2), "DeidentificationMethodCodeSequence");
    it->putAndInsertString(DCM_CodeValue, code[0]);
    it->putAndInsertString(DCM_CodingSchemeDesignator, "DCM");
    it->putAndInsertString(DCM_CodeMeaning, code[1]);
  }
}

std::string apply_output_series(DcmItem& item, const StudyContext& study, const DicomSource& source, const std::string& modality,
                                int series_number, const std::string& description) {
  const std::string series_uid = new_uid();
  const std::string date = now("%Y%m%d"), time = now("%H%M%S");
  check(item.putAndInsertString(DCM_Modality, modality.c_str()), "Modality");
  check(item.putAndInsertString(DCM_SeriesInstanceUID, series_uid.c_str()), "SeriesInstanceUID");
  check(item.putAndInsertString(DCM_SeriesNumber, std::to_string(series_number).c_str()), "SeriesNumber");
  check(item.putAndInsertString(DCM_SeriesDescription, description.c_str()), "SeriesDescription");
  check(item.putAndInsertString(DCM_SeriesDate, date.c_str()), "SeriesDate");
  check(item.putAndInsertString(DCM_SeriesTime, time.c_str()), "SeriesTime");
  check(item.putAndInsertString(DCM_Manufacturer, "MandiSym"), "Manufacturer");
  check(item.putAndInsertString(DCM_ManufacturerModelName, "mandisym"), "ManufacturerModelName");
  check(item.putAndInsertString(DCM_SoftwareVersions, study.tool_version.c_str()), "SoftwareVersions");
  check(item.putAndInsertString(DCM_InstanceNumber, "1"), "InstanceNumber");
  check(item.putAndInsertString(DCM_ContentDate, date.c_str()), "ContentDate");
  check(item.putAndInsertString(DCM_ContentTime, time.c_str()), "ContentTime");
  check(item.putAndInsertString(DCM_InstanceCreationDate, date.c_str()), "InstanceCreationDate");
  check(item.putAndInsertString(DCM_InstanceCreationTime, time.c_str()), "InstanceCreationTime");
  if (!source.frame_of_reference_uid.empty())
    check(item.putAndInsertString(DCM_FrameOfReferenceUID, source.frame_of_reference_uid.c_str()), "FrameOfReferenceUID");
  apply_study_context(item, study);
  return series_uid;
}

void reference_source_series(DcmItem& item, const DicomSource& source) {
  item.findAndDeleteElement(DCM_ReferencedSeriesSequence);
  DcmItem* series = nullptr;
  check(item.findOrCreateSequenceItem(DCM_ReferencedSeriesSequence, series, -2), "ReferencedSeriesSequence");
  check(series->putAndInsertString(DCM_SeriesInstanceUID, source.series_uid.c_str()), "ReferencedSeries UID");
  std::string last;
  for (const DicomSourceFrame& f : source.frames) {
    if (f.sop_instance_uid == last) continue;  // the frames of one multi-frame file
    last = f.sop_instance_uid;
    DcmItem* inst = nullptr;
    check(series->findOrCreateSequenceItem(DCM_ReferencedInstanceSequence, inst, -2), "ReferencedInstanceSequence");
    inst->putAndInsertString(DCM_ReferencedSOPClassUID, source.sop_class_uid.c_str());
    inst->putAndInsertString(DCM_ReferencedSOPInstanceUID, f.sop_instance_uid.c_str());
  }
}

Written save(DcmFileFormat& file, const std::string& path, const std::string& what) {
  DcmDataset& ds = *file.getDataset();
  Written w;
  w.path = path;
  w.what = what;
  OFString v;
  if (ds.findAndGetOFString(DCM_SOPClassUID, v).good()) w.sop_class_uid = v.c_str();
  if (ds.findAndGetOFString(DCM_SOPInstanceUID, v).good()) w.sop_instance_uid = v.c_str();
  if (ds.findAndGetOFString(DCM_SeriesInstanceUID, v).good()) w.series_instance_uid = v.c_str();
  // Written under a temporary name, then renamed: a reader never sees half an object.
  const std::string partial = path + ".partial";
  const OFCondition c = file.saveFile(partial.c_str(), EXS_LittleEndianExplicit);
  std::error_code ec;
  if (c.good()) std::filesystem::rename(partial, path, ec);
  if (c.bad() || ec) {
    std::filesystem::remove(partial, ec);
    throw Error(ExitCode::OutputFailed, path + ": cannot write the DICOM " + what + ": " + (c.bad() ? c.text() : "rename failed"));
  }
  return w;
}

}  // namespace ms::dicomout
