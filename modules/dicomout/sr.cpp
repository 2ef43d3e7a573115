// results.json as a Comprehensive 3D SR following TID 1500 (Measurement
// Report), built with DCMTK's dcmsr/cmr template classes (docs/pacs.md,
// "Measurement report"). Content tree:
//
//   CONTAINER (126000, DCM, "Imaging Measurement Report")          TID 1500
//     language, device observer "MandiSym", procedure reported (CT)
//     (no Image Library: the SR references no image directly)
//     CONTAINER (126010, DCM, "Imaging Measurements")
//       CONTAINER Measurement Group "MandiSym mandible"               TID 1411
//         tracking id + UID, Finding = Mandible, Referenced Segment (the
//         SEG's segment), Source series for segmentation (the CT series),
//         Finding Site = Mandible
//         NUM volume, SAF score, mirror mean/RMS/p95/max, menton deviation
//         SCOORD3D POINT per landmark (source Frame of Reference)  [extension]
//       CONTAINER Measurement Group "MandiSym mandible, left"        TID 1411
//         ... Finding Site = Mandible, Laterality = Left; NUM per bilateral L
//       CONTAINER Measurement Group "MandiSym mandible, right"       (R values)
//       CONTAINER Measurement Group "MandiSym mandible, left minus right"
//         ... Laterality = Bilateral; NUM per bilateral diff, each with
//         Derivation = (MSYM210, 99MANDISYM, "Left minus right difference")
//     CONTAINER Qualitative Evaluations
//       CODE QC status = passed | passed with warnings | failed
//       TEXT Failed quality control check = <check name>   (one per failed check)
//
// Each NUM carries its value as DS (Numeric Value, 16 characters) and as FD
// (Floating Point Value, exact), UCUM units, and Algorithm Identification
// (MandiSym <version>). A value that is null or absent in results.json is
// left out; a group left without content is left out.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <dcmtk/dcmsr/cmr/tid1500.h>
#include <dcmtk/dcmsr/codes/dcm.h>
#include <dcmtk/dcmsr/dsrdoc.h>

#include "core/error.h"
#include "dicomout/common.h"

namespace ms::dicomout {

namespace {

using Report = TID1500_MeasurementReport;
using Group = Report::TID1411_Measurements;

// ---------------------------------------------------------------------------
// The code table: every concept the SR uses that is MandiSym's own (coding
// scheme 99MANDISYM, declared in the Coding Scheme Identification Sequence),
// and which results.json value each concept carries. docs/pacs.md lists it.
// ---------------------------------------------------------------------------
const char* const kScheme = "99MANDISYM";
const char* const kSchemeUid = "2.25.138323834927510837936720615204437378530";  // fixed, UUID-derived
// Device Observer UID of the MandiSym software (fixed, UUID-derived).
const char* const kDeviceObserverUid = "2.25.183529720703714097390392044690326898345";

struct Unit {
  const char* code;
  const char* meaning;
};
const Unit kMm{"mm", "millimeter"}, kDeg{"deg", "degree"}, kRad{"rad", "radian"}, kCm3{"cm3", "cubic centimeter"};

// Whole-mandible measurements: JSON pointer into results.json, concept, unit,
// factor from the JSON value to the SR value.
struct MandibleMeasure {
  const char* pointer;
  const char* code;
  const char* scheme;
  const char* meaning;
  Unit unit;
  double factor;
};
const MandibleMeasure kMandibleMeasures[] = {
    {"/segmentation/volume_mm3", "118565006", "SCT", "Volume", kCm3, 1e-3},
    {"/scores/saf/score", "MSYM101", kScheme, "SAF score", kRad, 1},
    {"/scores/mirror/mean_mm", "MSYM102", kScheme, "Mirror distance mean", kMm, 1},
    {"/scores/mirror/rms_mm", "MSYM103", kScheme, "Mirror distance RMS", kMm, 1},
    {"/scores/mirror/p95_mm", "MSYM104", kScheme, "Mirror distance 95th percentile", kMm, 1},
    {"/scores/mirror/max_mm", "MSYM105", kScheme, "Mirror distance maximum", kMm, 1},
    {"/interpretation/menton_deviation/value", "MSYM106", kScheme, "Menton deviation", kMm, 1},
};

// Bilateral measures: key under scores.bilateral (its L, R and diff = L - R).
// Keys not listed here are not written.
struct BilateralMeasure {
  const char* key;
  const char* code;
  const char* meaning;
  Unit unit;
};
const BilateralMeasure kBilateralMeasures[] = {
    {"ramus_height_mm", "MSYM201", "Ramus height (condylion to gonion)", kMm},
    {"body_length_mm", "MSYM202", "Mandibular body length (gonion to menton)", kMm},
    {"gonial_angle_deg", "MSYM203", "Gonial angle", kDeg},
    {"condyle_to_plane_mm", "MSYM204", "Condylion distance to symmetry plane", kMm},
    {"gonion_to_plane_mm", "MSYM205", "Gonion distance to symmetry plane", kMm},
};
const char* const kLeftMinusRight[] = {"MSYM210", "Left minus right difference"};  // Derivation of the diffs

// Landmarks: key under landmarks ([x, y, z] LPS mm) -> SCOORD3D POINT concept.
struct LandmarkConcept {
  const char* key;
  const char* code;
  const char* meaning;
};
const LandmarkConcept kLandmarks[] = {
    {"Co_L", "MSYM301", "Condylion, left"},  {"Co_R", "MSYM302", "Condylion, right"},
    {"Cr_L", "MSYM303", "Coronion, left"},   {"Cr_R", "MSYM304", "Coronion, right"},
    {"Go_L", "MSYM305", "Gonion, left"},     {"Go_R", "MSYM306", "Gonion, right"},
    {"Me", "MSYM307", "Menton"},             {"Pog", "MSYM308", "Pogonion"},
};

// QC: qc.status as a coded qualitative evaluation, failed checks as text.
const char* const kQcStatusConcept[] = {"MSYM401", "Quality control status"};
struct QcStatusValue {
  const char* status;
  const char* code;
  const char* meaning;
};
const QcStatusValue kQcStatusValues[] = {
    {"pass", "MSYM402", "Quality control passed"},
    {"warn", "MSYM403", "Quality control passed with warnings"},
    {"fail", "MSYM404", "Quality control failed"},
};
const char* const kFailedCheckConcept[] = {"MSYM405", "Failed quality control check"};

// Standard codes.
const DSRCodedEntryValue kMandible("91609006", "SCT", "Mandible");
const DSRCodedEntryValue kLeft("7771000", "SCT", "Left"), kRight("24028007", "SCT", "Right"), kBilateral("51440002", "SCT", "Bilateral");
const DSRCodedEntryValue kMeasurementGroup(CODE_DCM_MeasurementGroup), kTrackingIdentifier(CODE_DCM_TrackingIdentifier);
const char* const kMandibleGroup = "MandiSym mandible";  // the group holding the landmarks

// ---------------------------------------------------------------------------

DSRCodedEntryValue private_code(const char* value, const char* meaning) { return DSRCodedEntryValue(value, kScheme, meaning); }

// A decimal string value (VR DS: at most 16 characters), as many significant
// digits as fit.
std::string ds(double v) {
  char b[40];
  for (int digits = 17; digits >= 4; --digits) {
    std::snprintf(b, sizeof b, "%.*g", digits, v);
    if (std::string(b).size() <= 16) break;
  }
  return b;
}

// The finite number at pointer ("/a/b/c", object members only) in results,
// or false when it is absent, null or not a number.
bool number_at(const Json& results, const std::string& pointer, double& out) {
  const Json* v = &results;
  for (std::size_t begin = 1; v && begin <= pointer.size();) {
    const std::size_t end = std::min(pointer.find('/', begin), pointer.size());
    v = find_member(*v, pointer.substr(begin, end - begin));
    begin = end + 1;
  }
  if (!v || !v->is_number()) return false;
  out = v->get<double>();
  return std::isfinite(out);
}

// One NUM of a measurement group.
struct Num {
  DSRCodedEntryValue concept;
  double value;
  Unit unit;
  bool left_minus_right;
};

// One SCOORD3D POINT.
struct Point {
  DSRCodedEntryValue concept;
  float xyz[3];
};

// One TID 1411 group before it is written.
struct GroupContent {
  std::string tracking_id;
  DSRCodedEntryValue laterality;  // empty: none
  std::vector<Num> nums;
  std::vector<Point> points;
};

// The whole-mandible group: the measures of kMandibleMeasures and the
// landmarks that results.json has.
GroupContent mandible_group(const Json& results) {
  GroupContent g{kMandibleGroup, DSRCodedEntryValue(), {}, {}};
  for (const MandibleMeasure& m : kMandibleMeasures) {
    double v = 0;
    if (number_at(results, m.pointer, v)) g.nums.push_back({DSRCodedEntryValue(m.code, m.scheme, m.meaning), v * m.factor, m.unit, false});
  }
  const Json* landmarks = find_member(results, "landmarks");
  for (const LandmarkConcept& l : kLandmarks) {
    const Json* p = landmarks ? find_member(*landmarks, l.key) : nullptr;
    if (!p || !p->is_array() || p->size() != 3) continue;
    Point pt{private_code(l.code, l.meaning), {0, 0, 0}};
    bool ok = true;
    for (int a = 0; a < 3; ++a) {
      ok = ok && (*p)[a].is_number() && std::isfinite((*p)[a].get<double>());
      if (ok) pt.xyz[a] = static_cast<float>((*p)[a].get<double>());
    }
    if (ok) g.points.push_back(pt);
  }
  return g;
}

// The group of one side ("L", "R") or of the differences ("diff").
GroupContent bilateral_group(const Json& results, const std::string& which) {
  GroupContent g;
  if (which == "L") g = {"MandiSym mandible, left", kLeft, {}, {}};
  if (which == "R") g = {"MandiSym mandible, right", kRight, {}, {}};
  if (which == "diff") g = {"MandiSym mandible, left minus right", kBilateral, {}, {}};
  for (const BilateralMeasure& m : kBilateralMeasures) {
    double v = 0;
    const std::string pointer = std::string("/scores/bilateral/") + m.key + "/" + which;
    if (number_at(results, pointer, v)) g.nums.push_back({private_code(m.code, m.meaning), v, m.unit, which == "diff"});
  }
  return g;
}

// One TID 1419 measurement: value as DS and FD, UCUM unit, derivation for
// the differences, algorithm MandiSym <version>.
void add_num(Group& group, const Num& n, const std::string& version) {
  Group::MeasurementValue value(ds(n.value).c_str(), CID7181_AbstractMultiDimensionalImageModelComponentUnits(
                                                         DSRCodedEntryValue(n.unit.code, "UCUM", n.unit.meaning)));
  check(value.setFloatingPointRepresentation(n.value), "FloatingPointValue");
  check(group.addMeasurement(CID7469_GenericIntensityAndSizeMeasurements(n.concept), value),
        "measurement " + std::string(n.concept.getCodeMeaning().c_str()));
  Group::TID1419_Measurement& m = group.getMeasurement();
  if (n.left_minus_right)
    check(m.setDerivation(CID7464_GeneralRegionOfInterestMeasurementModifiers(private_code(kLeftMinusRight[0], kLeftMinusRight[1]))),
          "Derivation");
  check(m.setAlgorithmIdentification("MandiSym", version.empty() ? "unknown" : version.c_str()), "AlgorithmIdentification");
}

// Moves the tree's cursor to the measurement group with this tracking
// identifier; returns its node ID (0 when there is none).
size_t goto_group(DSRDocumentTree& tree, const std::string& tracking_id) {
  for (size_t group = tree.gotoNamedNode(kMeasurementGroup); group != 0; group = tree.gotoNextNamedNode(kMeasurementGroup)) {
    const bool match = tree.gotoNamedChildNode(kTrackingIdentifier) != 0 &&
                       tree.getCurrentContentItem().getStringValue() == tracking_id.c_str();
    tree.gotoNode(group);
    if (match) return group;
  }
  return 0;
}

// The landmarks extend TID 1411 (extensible): CONTAINS SCOORD3D POINT items
// below the mandible group, in the source Frame of Reference. The template
// classes cannot add them, so they go in through the document tree.
void add_landmarks(DSRDocumentTree& tree, const std::vector<Point>& points, const std::string& frame_of_reference) {
  if (points.empty()) return;
  const size_t group = goto_group(tree, kMandibleGroup);
  if (group == 0) throw Error(ExitCode::Internal, "DICOM SR: no measurement group for the landmarks");
  for (const Point& p : points) {
    tree.gotoNode(group);
    if (tree.addContentItem(DSRTypes::RT_contains, DSRTypes::VT_SCoord3D, DSRTypes::AM_belowCurrent) == 0)
      throw Error(ExitCode::Internal, "DICOM SR: cannot add a SCOORD3D item");
    DSRContentItem& item = tree.getCurrentContentItem();
    check(item.setConceptName(p.concept), "SCOORD3D concept");
    DSRSpatialCoordinates3DValue coords(DSRTypes::GT3_Point);
    coords.getGraphicDataList().addItem(p.xyz[0], p.xyz[1], p.xyz[2]);
    check(coords.setFrameOfReferenceUID(frame_of_reference.c_str()), "ReferencedFrameOfReferenceUID");
    check(item.setSpatialCoordinates3D(coords), "SCOORD3D " + std::string(p.concept.getCodeMeaning().c_str()));
  }
}

// A TID 1411 group: tracking, finding, the SEG segment, the source series,
// finding site (with laterality), then the NUMs and the points.
void add_group(Report& report, const GroupContent& g, const DicomSource& source, const SegmentRef& seg, const std::string& version) {
  if (g.nums.empty() && g.points.empty()) return;
  check(report.addVolumetricROIMeasurements(), "new measurement group");
  Group& group = report.getVolumetricROIMeasurements();
  check(group.setTrackingIdentifier(g.tracking_id.c_str()), "TrackingIdentifier");
  check(group.setTrackingUniqueIdentifier(new_uid().c_str()), "TrackingUniqueIdentifier");
  check(group.setFinding(kMandible), "Finding");
  DSRImageReferenceValue segment(seg.sop_class_uid.c_str(), seg.sop_instance_uid.c_str());
  segment.getSegmentList().addItem(static_cast<Uint16>(seg.segment_number));
  check(group.setReferencedSegment(segment), "ReferencedSegment");
  check(group.setSourceSeriesForSegmentation(source.series_uid.c_str()), "SourceSeriesForSegmentation");
  check(group.addFindingSite(kMandible, CID244e_Laterality(g.laterality)), "FindingSite");
  for (const Num& n : g.nums) add_num(group, n, version);
}

// qc.status (coded) and the names of the checks that did not pass (text).
void add_qc(Report& report, const Json& results) {
  const Json* qc = find_member(results, "qc");
  const Json* status = qc ? find_member(*qc, "status") : nullptr;
  if (!status || !status->is_string()) return;
  const std::string s = status->get<std::string>();
  for (const QcStatusValue& v : kQcStatusValues)
    if (s == v.status)
      check(report.addQualitativeEvaluation(private_code(kQcStatusConcept[0], kQcStatusConcept[1]), private_code(v.code, v.meaning)),
            "QC status");
  const Json* checks = find_member(*qc, "checks");
  if (s == "pass" || !checks || !checks->is_array()) return;
  for (const Json& c : *checks) {
    const Json* passed = find_member(c, "passed");
    const Json* name = find_member(c, "name");
    if (!passed || !passed->is_boolean() || passed->get<bool>() || !name || !name->is_string()) continue;
    check(report.addQualitativeEvaluation(private_code(kFailedCheckConcept[0], kFailedCheckConcept[1]), name->get<std::string>().c_str()),
          "failed QC check");
  }
}

// The TID 1500 report: title, language, observer, procedure, groups, QC.
void build_report(Report& report, const Json& results, const GroupContent& mandible, const DicomSource& source,
                  const StudyContext& study, const SegmentRef& seg) {
  check(report.createNewMeasurementReport(CID7021_MeasurementReportDocumentTitles::ImagingMeasurementReport), "measurement report");
  check(report.setLanguage(CID5000_Languages::English), "language");
  check(report.getObservationContext().addDeviceObserver(kDeviceObserverUid, "MandiSym", "MandiSym", "mandisym"), "device observer");
  check(report.addProcedureReported(CID100_QuantitativeDiagnosticImagingProcedures::CTUnspecifiedBodyRegion), "procedure reported");
  add_group(report, mandible, source, seg, study.tool_version);
  for (const char* which : {"L", "R", "diff"}) add_group(report, bilateral_group(results, which), source, seg, study.tool_version);
  add_qc(report, results);
  if (!report.isValid()) throw Error(ExitCode::Internal, "DICOM SR: the TID 1500 measurement report is not valid");
}

// SR Document General: the CT instances and the SEG as the evidence; the
// private coding scheme.
void add_evidence_and_scheme(DSRDocument& doc, const DicomSource& source, const SegmentRef& seg) {
  DSRSOPInstanceReferenceList& evidence = doc.getCurrentRequestedProcedureEvidence();
  std::string last;
  for (const DicomSourceFrame& f : source.frames) {
    if (f.sop_instance_uid == last) continue;  // the frames of one multi-frame file
    last = f.sop_instance_uid;
    check(evidence.addItem(source.study_uid.c_str(), source.series_uid.c_str(), source.sop_class_uid.c_str(), f.sop_instance_uid.c_str()),
          "evidence " + f.sop_instance_uid);
  }
  check(evidence.addItem(source.study_uid.c_str(), seg.series_instance_uid.c_str(), seg.sop_class_uid.c_str(),
                         seg.sop_instance_uid.c_str()),
        "evidence (SEG)");
  DSRCodingSchemeIdentificationList& schemes = doc.getCodingSchemeIdentification();
  check(schemes.addItem(kScheme), "CodingSchemeIdentification");
  check(schemes.setCodingSchemeUID(kSchemeUid), "CodingSchemeUID");
  check(schemes.setCodingSchemeName("MandiSym measurement concepts"), "CodingSchemeName");
  check(schemes.setCodingSchemeResponsibleOrganization("MandiSym project"), "CodingSchemeResponsibleOrganization");
}

}  // namespace

Written write_sr(const Json& results, const DicomSource& source, const StudyContext& study, const SegmentRef& seg,
                 const std::string& path) {
  if (source.frames.empty()) throw Error(ExitCode::Internal, "DICOM SR: the source series has no frames");
  if (seg.series_instance_uid.empty()) throw Error(ExitCode::Internal, "DICOM SR: the SEG's SeriesInstanceUID is not given");
  const GroupContent mandible = mandible_group(results);
  Report report;
  build_report(report, results, mandible, source, study, seg);
  DSRDocument doc(DSRTypes::DT_Comprehensive3DSR);
  check(doc.setTreeFromRootTemplate(report, OFTrue /*expand the included templates*/), "TID 1500 content tree");
  // The template makes an Enhanced SR; SCOORD3D needs Comprehensive 3D SR.
  check(doc.changeDocumentType(DSRTypes::DT_Comprehensive3DSR), "Comprehensive 3D SR");
  add_landmarks(doc.getTree(), mandible.points, source.frame_of_reference_uid);
  add_evidence_and_scheme(doc, source, seg);
  check(doc.completeDocument(), "CompletionFlag");
  DcmFileFormat file;
  check(doc.write(*file.getDataset()), "SR dataset");
  DcmDataset& dataset = *file.getDataset();
  apply_output_series(dataset, study, source, "SR", 9702, "MandiSym measurement report");
  dataset.findAndDeleteElement(DCM_FrameOfReferenceUID);  // not part of the SR IODs: SCOORD3D items carry it
  return save(file, path, "SR");
}

}  // namespace ms::dicomout
