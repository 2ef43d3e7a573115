// The DICOM SR (TID 1500) read back with DCMTK's DSRDocument and compared
// with the results.json it was written from. The expected mapping from
// results.json to concepts is written here, independently of sr.cpp's table,
// so that a wrong code, unit, group, value or a value written for a missing
// result fails a test.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmsr/dsrdoc.h>

#include "core/error.h"
#include "core/json_text.h"
#include "dicomout/dicomout.h"
#include "io/volume_io.h"

namespace fs = std::filesystem;
using ms::Json;

namespace {

const fs::path kSample = fs::path(MANDISYM_SOURCE_DIR) / "sample_dicom" / "symmetric" / "dicom";
const char* const kSegClass = UID_SegmentationStorage;
const char* const kPrivate = "99MANDISYM";

// ---- The expected mapping, results.json -> SR (independent of sr.cpp) ----

// A NUM: where its value is in results.json, its concept, unit, the
// laterality of its group (SCT code, "" for the whole mandible) and whether
// it carries the left-minus-right derivation.
struct ExpectedNum {
  std::string pointer, scheme, code, unit, laterality;
  bool diff;
  double factor;
};

std::vector<ExpectedNum> expected_nums() {
  std::vector<ExpectedNum> e = {
      {"/segmentation/volume_mm3", "SCT", "118565006", "cm3", "", false, 1e-3},
      {"/scores/saf/score", kPrivate, "MSYM101", "rad", "", false, 1},
      {"/scores/mirror/mean_mm", kPrivate, "MSYM102", "mm", "", false, 1},
      {"/scores/mirror/rms_mm", kPrivate, "MSYM103", "mm", "", false, 1},
      {"/scores/mirror/p95_mm", kPrivate, "MSYM104", "mm", "", false, 1},
      {"/scores/mirror/max_mm", kPrivate, "MSYM105", "mm", "", false, 1},
      {"/interpretation/menton_deviation/value", kPrivate, "MSYM106", "mm", "", false, 1},
  };
  const std::vector<std::vector<std::string>> bilateral = {{"ramus_height_mm", "MSYM201", "mm"},
                                                           {"body_length_mm", "MSYM202", "mm"},
                                                           {"gonial_angle_deg", "MSYM203", "deg"},
                                                           {"condyle_to_plane_mm", "MSYM204", "mm"},
                                                           {"gonion_to_plane_mm", "MSYM205", "mm"}};
  for (const auto& b : bilateral) {
    const std::string p = "/scores/bilateral/" + b[0] + "/";
    e.push_back({p + "L", kPrivate, b[1], b[2], "7771000", false, 1});
    e.push_back({p + "R", kPrivate, b[1], b[2], "24028007", false, 1});
    e.push_back({p + "diff", kPrivate, b[1], b[2], "51440002", true, 1});
  }
  return e;
}
const std::set<std::string> kBilateralKeys = {"ramus_height_mm", "body_length_mm", "gonial_angle_deg", "condyle_to_plane_mm",
                                              "gonion_to_plane_mm"};
const std::map<std::string, std::string> kLandmarkCodes = {{"Co_L", "MSYM301"}, {"Co_R", "MSYM302"}, {"Cr_L", "MSYM303"},
                                                           {"Cr_R", "MSYM304"}, {"Go_L", "MSYM305"}, {"Go_R", "MSYM306"},
                                                           {"Me", "MSYM307"},   {"Pog", "MSYM308"}};
const std::map<std::string, std::string> kQcCodes = {{"pass", "MSYM402"}, {"warn", "MSYM403"}, {"fail", "MSYM404"}};

// ---- The SR's content tree, read back into plain values ----

struct Node {
  DSRTypes::E_ValueType type = DSRTypes::VT_invalid;
  std::string concept_scheme, concept_code;
  std::string text;                      // TEXT, UIDREF
  std::string code_scheme, code_value;   // CODE
  std::string numeric, unit;             // NUM: DS value, UCUM unit
  double fd = NAN;                       // NUM: FloatingPointValue
  std::vector<float> xyz;                // SCOORD3D
  std::string graphic_type, frame_of_reference;
  std::string ref_class, ref_instance;   // IMAGE
  std::vector<unsigned> segments;
  std::vector<Node> children;

  bool is(const std::string& scheme, const std::string& code) const { return concept_scheme == scheme && concept_code == code; }
  const Node* child(const std::string& scheme, const std::string& code) const {
    for (const Node& c : children)
      if (c.is(scheme, code)) return &c;
    return nullptr;
  }
};

Node node_of(const DSRContentItem& item) {
  Node n;
  n.type = item.getValueType();
  n.concept_scheme = item.getConceptName().getCodingSchemeDesignator().c_str();
  n.concept_code = item.getConceptName().getCodeValue().c_str();
  n.text = item.getStringValue().c_str();
  n.code_scheme = item.getCodeValue().getCodingSchemeDesignator().c_str();
  n.code_value = item.getCodeValue().getCodeValue().c_str();
  if (n.type == DSRTypes::VT_Num) {
    const DSRNumericMeasurementValue& v = item.getNumericValue();
    n.numeric = v.getNumericValue().c_str();
    n.unit = v.getMeasurementUnit().getCodeValue().c_str();
    Float64 fd = 0;
    if (v.getFloatingPointRepresentation(fd).good()) n.fd = fd;
  }
  if (n.type == DSRTypes::VT_SCoord3D) {
    DSRSpatialCoordinates3DValue c = item.getSpatialCoordinates3D();  // its point list has no const access
    n.graphic_type = DSRTypes::graphicType3DToEnumeratedValue(c.getGraphicType());
    n.frame_of_reference = c.getFrameOfReferenceUID().c_str();
    const DSRGraphicData3DList& l = c.getGraphicDataList();
    for (size_t i = 1; i <= l.getNumberOfItems(); ++i) {
      const DSRGraphicData3DItem& p = l.getItem(i);
      n.xyz.insert(n.xyz.end(), {p.XCoord, p.YCoord, p.ZCoord});
    }
  }
  if (n.type == DSRTypes::VT_Image) {
    const DSRImageReferenceValue& r = item.getImageReference();
    n.ref_class = r.getSOPClassUID().c_str();
    n.ref_instance = r.getSOPInstanceUID().c_str();
    for (size_t i = 1; i <= r.getSegmentList().getNumberOfItems(); ++i) n.segments.push_back(r.getSegmentList().getItem(i));
  }
  return n;
}

// The subtree at the tree's cursor.
Node read_subtree(DSRDocumentTree& tree) {
  Node n = node_of(tree.getCurrentContentItem());
  if (tree.goDown() != 0) {
    do n.children.push_back(read_subtree(tree));
    while (tree.gotoNext() != 0);
    tree.goUp();
  }
  return n;
}

struct SrFile {
  DcmFileFormat file;
  DSRDocument doc;
  Node root;
};

std::unique_ptr<SrFile> read_sr(const std::string& path) {
  auto sr = std::make_unique<SrFile>();
  EXPECT_TRUE(sr->file.loadFile(path.c_str()).good()) << path;
  const OFCondition c = sr->doc.read(*sr->file.getDataset());
  EXPECT_TRUE(c.good()) << path << ": " << c.text();
  DSRDocumentTree& tree = sr->doc.getTree();
  if (tree.gotoRoot() != 0) sr->root = read_subtree(tree);
  return sr;
}

// Every node below n, depth first.
void collect(const Node& n, std::vector<const Node*>& out) {
  for (const Node& c : n.children) {
    out.push_back(&c);
    collect(c, out);
  }
}

std::vector<const Node*> groups_of(const Node& root) {
  std::vector<const Node*> all, groups;
  collect(root, all);
  for (const Node* n : all)
    if (n->is("DCM", "125007")) groups.push_back(n);
  return groups;
}

// The laterality of a measurement group ("" when its finding site has none).
std::string laterality_of(const Node& group) {
  const Node* site = group.child("SCT", "363698007");
  const Node* lat = site ? site->child("SCT", "272741003") : nullptr;
  return lat ? lat->code_value : "";
}

struct FoundNum {
  const Node* num;
  std::string laterality;
  bool diff;
};

std::vector<FoundNum> nums_of(const Node& root) {
  std::vector<FoundNum> out;
  for (const Node* g : groups_of(root))
    for (const Node& c : g->children) {
      if (c.type != DSRTypes::VT_Num) continue;
      const Node* derivation = c.child("DCM", "121401");
      const bool diff = derivation && derivation->code_scheme == kPrivate && derivation->code_value == "MSYM210";
      out.push_back({&c, laterality_of(*g), diff});
    }
  return out;
}

std::vector<const Node*> nodes_with(const Node& root, const std::string& scheme, const std::string& code) {
  std::vector<const Node*> all, out;
  collect(root, all);
  for (const Node* n : all)
    if (n->is(scheme, code)) out.push_back(n);
  return out;
}

// The number at a JSON pointer, or nullptr when absent, null, not a number
// or when the path does not resolve.
const Json* number_at(const Json& results, const std::string& pointer) {
  try {
    const Json& v = results.at(Json::json_pointer(pointer));
    return v.is_number() ? &v : nullptr;
  } catch (const Json::exception&) {
    return nullptr;
  }
}

// Every expected NUM whose results.json value is a number is in the SR once,
// with its unit and value (DS within 1e-9 relative, FD exact); no other NUM
// is there (a missing value is not written as 0).
void expect_numbers_match(const Json& results, const Node& root) {
  const std::vector<FoundNum> found = nums_of(root);
  std::size_t present = 0;
  for (const ExpectedNum& e : expected_nums()) {
    const Json* value = number_at(results, e.pointer);
    const bool has = value != nullptr;
    std::vector<const FoundNum*> hits;
    for (const FoundNum& f : found)
      if (f.num->is(e.scheme, e.code) && f.laterality == e.laterality && f.diff == e.diff) hits.push_back(&f);
    if (!has) {
      EXPECT_TRUE(hits.empty()) << e.pointer << " is missing in results.json but written to the SR";
      continue;
    }
    ++present;
    ASSERT_EQ(hits.size(), 1u) << e.pointer << " -> " << e.scheme << " " << e.code;
    const Node& n = *hits[0]->num;
    const double want = value->get<double>() * e.factor;
    EXPECT_EQ(n.unit, e.unit) << e.pointer;
    EXPECT_LE(n.numeric.size(), 16u) << e.pointer;
    const double ds = std::strtod(n.numeric.c_str(), nullptr);
    EXPECT_NEAR(ds, want, std::max(1e-9 * std::abs(want), 1e-15)) << e.pointer << " DS " << n.numeric;
    EXPECT_EQ(n.fd, want) << e.pointer << " FloatingPointValue";
  }
  EXPECT_EQ(found.size(), present) << "NUM items in the SR vs values in results.json";
}

// ---- Fixture: one real run of the sample, its DICOM source and study ----

fs::path scratch(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("mandisym_sr_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string uid() {
  char b[100];
  return dcmGenerateUniqueIdentifier(b, SITE_INSTANCE_UID_ROOT);
}

class SrSample : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = scratch("run");
    const std::string cmd =
        std::string(MANDISYM_BINARY) + " run " + kSample.string() + " -o " + (dir_ / "out").string() + " --quiet --no-figures";
    const int rc = std::system(cmd.c_str());
    ASSERT_EQ(rc, 0) << cmd;
    std::ifstream in(dir_ / "out" / "results.json");
    std::stringstream text;
    text << in.rdbuf();
    results_ = ms::parse_json(text.str());
    source_ = *ms::io::read_scan(kSample.string()).dicom;
    study_ = ms::dicomout::read_study_context(*source_, false, "0.1.0-test");
    seg_.sop_class_uid = kSegClass;
    seg_.sop_instance_uid = uid();
    seg_.series_instance_uid = uid();
    seg_.segment_number = 1;
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  // Writes the SR of results and returns its path.
  static std::string write(const Json& results, const std::string& name) {
    const std::string path = (dir_ / (name + ".dcm")).string();
    const ms::dicomout::Written w = ms::dicomout::write_sr(results, *source_, study_, seg_, path);
    EXPECT_EQ(w.path, path);
    EXPECT_EQ(w.what, "SR");
    EXPECT_EQ(w.sop_class_uid, UID_Comprehensive3DSRStorage);
    return path;
  }

  static inline fs::path dir_;
  static inline Json results_;
  static inline std::optional<ms::DicomSource> source_;
  static inline ms::dicomout::StudyContext study_;
  static inline ms::dicomout::SegmentRef seg_;
};

// A results.json with QC failed, a landmark null and one absent, no SAF
// score and one bilateral value null.
Json degraded(Json r) {
  r["qc"]["status"] = "fail";
  r["qc"]["checks"][0]["passed"] = false;
  r["qc"]["checks"][3]["passed"] = false;
  r["landmarks"]["Me"] = nullptr;
  r["landmarks"].erase("Pog");
  r["scores"]["saf"]["score"] = nullptr;
  r["scores"]["bilateral"]["gonial_angle_deg"]["L"] = nullptr;
  return r;
}

// ---- Tests ----

TEST_F(SrSample, EveryNumberEqualsResultsJson) {
  for (const auto& [key, value] : results_.at("scores").at("bilateral").items())
    EXPECT_TRUE(kBilateralKeys.count(key)) << "bilateral measure " << key << " has no expected SR concept";
  const auto sr = read_sr(write(results_, "sample"));
  expect_numbers_match(results_, sr->root);
  EXPECT_GE(nums_of(sr->root).size(), 20u);  // the sample has every value
}

TEST_F(SrSample, MeasurementGroupsReferenceTheSegmentAndTheSourceSeries) {
  const auto sr = read_sr(write(results_, "groups"));
  EXPECT_TRUE(sr->root.is("DCM", "126000"));
  const std::vector<const Node*> groups = groups_of(sr->root);
  ASSERT_EQ(groups.size(), 4u);
  std::set<std::string> lateralities, tracking_uids;
  for (const Node* g : groups) {
    const Node* ref = g->child("DCM", "121191");
    ASSERT_TRUE(ref) << "Referenced Segment";
    EXPECT_EQ(ref->type, DSRTypes::VT_Image);
    EXPECT_EQ(ref->ref_class, seg_.sop_class_uid);
    EXPECT_EQ(ref->ref_instance, seg_.sop_instance_uid);
    EXPECT_EQ(ref->segments, std::vector<unsigned>{seg_.segment_number});
    const Node* series = g->child("DCM", "121232");
    ASSERT_TRUE(series) << "Source series for segmentation";
    EXPECT_EQ(series->text, source_->series_uid);
    const Node* finding = g->child("DCM", "121071");
    ASSERT_TRUE(finding);
    EXPECT_EQ(finding->code_scheme + " " + finding->code_value, "SCT 91609006");
    const Node* site = g->child("SCT", "363698007");
    ASSERT_TRUE(site);
    EXPECT_EQ(site->code_value, "91609006");
    const Node* tracking = g->child("DCM", "112040");
    ASSERT_TRUE(tracking);
    tracking_uids.insert(tracking->text);
    lateralities.insert(laterality_of(*g));
  }
  EXPECT_EQ(lateralities, (std::set<std::string>{"", "7771000", "24028007", "51440002"}));
  EXPECT_EQ(tracking_uids.size(), 4u);
}

TEST_F(SrSample, LandmarksAreScoord3dPointsInTheSourceFrameOfReference) {
  const auto sr = read_sr(write(results_, "landmarks"));
  ASSERT_FALSE(source_->frame_of_reference_uid.empty());
  std::size_t points = 0;
  for (const auto& [name, xyz] : results_.at("landmarks").items()) {
    ASSERT_TRUE(kLandmarkCodes.count(name)) << name;
    const auto hits = nodes_with(sr->root, kPrivate, kLandmarkCodes.at(name));
    ASSERT_EQ(hits.size(), 1u) << name;
    const Node& n = *hits[0];
    EXPECT_EQ(n.type, DSRTypes::VT_SCoord3D) << name;
    EXPECT_EQ(n.graphic_type, "POINT") << name;
    EXPECT_EQ(n.frame_of_reference, source_->frame_of_reference_uid) << name;
    ASSERT_EQ(n.xyz.size(), 3u) << name;
    for (int a = 0; a < 3; ++a) EXPECT_EQ(n.xyz[a], static_cast<float>(xyz[a].get<double>())) << name << " axis " << a;
    ++points;
  }
  EXPECT_EQ(points, 8u);
  std::vector<const Node*> all;
  collect(sr->root, all);
  std::size_t scoords = 0;
  for (const Node* n : all) scoords += n->type == DSRTypes::VT_SCoord3D;
  EXPECT_EQ(scoords, points);
}

TEST_F(SrSample, QcStatusPassHasNoFailedChecks) {
  ASSERT_EQ(results_.at("qc").at("status"), "pass");
  const auto sr = read_sr(write(results_, "qc_pass"));
  const auto status = nodes_with(sr->root, kPrivate, "MSYM401");
  ASSERT_EQ(status.size(), 1u);
  EXPECT_EQ(status[0]->type, DSRTypes::VT_Code);
  EXPECT_EQ(status[0]->code_scheme + " " + status[0]->code_value, std::string(kPrivate) + " MSYM402");
  EXPECT_TRUE(nodes_with(sr->root, kPrivate, "MSYM405").empty());
}

TEST_F(SrSample, FailedQcMissingLandmarksAndNoSafAreLeftOut) {
  const Json r = degraded(results_);
  const auto sr = read_sr(write(r, "degraded"));
  expect_numbers_match(r, sr->root);
  EXPECT_TRUE(nodes_with(sr->root, kPrivate, "MSYM101").empty()) << "SAF score written although null";
  EXPECT_TRUE(nodes_with(sr->root, kPrivate, "MSYM307").empty()) << "Me written although null";
  EXPECT_TRUE(nodes_with(sr->root, kPrivate, "MSYM308").empty()) << "Pog written although absent";
  EXPECT_EQ(nodes_with(sr->root, kPrivate, "MSYM301").size(), 1u);
  EXPECT_EQ(nodes_with(sr->root, kPrivate, "MSYM203").size(), 2u);  // gonial angle R and diff, not L
  const auto status = nodes_with(sr->root, kPrivate, "MSYM401");
  ASSERT_EQ(status.size(), 1u);
  EXPECT_EQ(status[0]->code_value, kQcCodes.at("fail"));
  std::multiset<std::string> failed, want;
  for (const Node* n : nodes_with(sr->root, kPrivate, "MSYM405")) {
    EXPECT_EQ(n->type, DSRTypes::VT_Text);
    failed.insert(n->text);
  }
  for (const Json& c : r.at("qc").at("checks"))
    if (!c.at("passed").get<bool>()) want.insert(c.at("name").get<std::string>());
  EXPECT_EQ(want.size(), 2u);
  EXPECT_EQ(failed, want);
}

TEST_F(SrSample, MalformedValuesAreLeftOutWithoutFailing) {
  Json r = results_;
  r["interpretation"] = nullptr;
  r["scores"]["bilateral"]["ramus_height_mm"] = Json::array({1.0, 2.0});
  r["scores"]["bilateral"]["body_length_mm"]["R"] = "83.9";
  r["scores"]["mirror"] = Json::array();
  r["landmarks"]["Go_L"] = Json::array({1.0, 2.0});
  r["landmarks"]["Go_R"] = Json::array({1.0, nullptr, 3.0});
  r["qc"]["checks"] = "none";
  r["qc"]["status"] = "warn";
  const auto sr = read_sr(write(r, "malformed"));
  expect_numbers_match(r, sr->root);
  EXPECT_TRUE(nodes_with(sr->root, kPrivate, "MSYM106").empty()) << "menton deviation without interpretation";
  EXPECT_TRUE(nodes_with(sr->root, kPrivate, "MSYM201").empty()) << "ramus height from an array";
  EXPECT_TRUE(nodes_with(sr->root, kPrivate, "MSYM305").empty()) << "Go_L with two coordinates";
  EXPECT_TRUE(nodes_with(sr->root, kPrivate, "MSYM306").empty()) << "Go_R with a null coordinate";
  EXPECT_EQ(nodes_with(sr->root, kPrivate, "MSYM301").size(), 1u);
  const auto status = nodes_with(sr->root, kPrivate, "MSYM401");
  ASSERT_EQ(status.size(), 1u);
  EXPECT_EQ(status[0]->code_value, kQcCodes.at("warn"));
  EXPECT_TRUE(nodes_with(sr->root, kPrivate, "MSYM405").empty());
}

TEST_F(SrSample, DocumentModulesEvidenceAndCodingScheme) {
  const std::string path = write(results_, "modules");
  const auto sr = read_sr(path);
  DcmDataset& ds = *sr->file.getDataset();
  auto str = [&ds](const DcmTagKey& tag) {
    OFString v;
    ds.findAndGetOFStringArray(tag, v);
    return std::string(v.c_str());
  };
  EXPECT_EQ(str(DCM_SOPClassUID), UID_Comprehensive3DSRStorage);
  EXPECT_EQ(str(DCM_Modality), "SR");
  EXPECT_EQ(str(DCM_SeriesNumber), "9702");
  EXPECT_EQ(str(DCM_SeriesDescription), "MandiSym measurement report");
  EXPECT_EQ(str(DCM_SoftwareVersions), "0.1.0-test");
  EXPECT_EQ(str(DCM_StudyInstanceUID), source_->study_uid);
  EXPECT_NE(str(DCM_SeriesInstanceUID), source_->series_uid);
  EXPECT_EQ(str(DCM_CompletionFlag), "COMPLETE");
  EXPECT_FALSE(ds.tagExists(DCM_FrameOfReferenceUID)) << "not in the SR IODs (the SCOORD3D items carry it)";
  DcmFileFormat ct;
  ASSERT_TRUE(ct.loadFile(source_->first_file.c_str()).good());
  OFString patient;
  ct.getDataset()->findAndGetOFString(DCM_PatientID, patient);
  EXPECT_EQ(str(DCM_PatientID), patient.c_str());
  EXPECT_EQ(sr->doc.getDocumentType(), DSRTypes::DT_Comprehensive3DSR);
  OFString mapping, template_id;
  EXPECT_TRUE(sr->doc.getTree().getTemplateIdentification(template_id, mapping).good());
  EXPECT_EQ(std::string(template_id.c_str()) + " " + mapping.c_str(), "1500 DCMR");
  // Evidence: every CT instance and the SEG.
  DSRSOPInstanceReferenceList& evidence = sr->doc.getCurrentRequestedProcedureEvidence();
  std::set<std::string> ct_instances;
  for (const ms::DicomSourceFrame& f : source_->frames) ct_instances.insert(f.sop_instance_uid);
  for (const std::string& i : ct_instances)
    EXPECT_TRUE(evidence.gotoItem(source_->study_uid.c_str(), source_->series_uid.c_str(), i.c_str()).good()) << i;
  EXPECT_TRUE(evidence.gotoItem(source_->study_uid.c_str(), seg_.series_instance_uid.c_str(), seg_.sop_instance_uid.c_str()).good());
  EXPECT_EQ(evidence.getNumberOfInstances(), ct_instances.size() + 1);
  // The private coding scheme is declared.
  DSRCodingSchemeIdentificationList& schemes = sr->doc.getCodingSchemeIdentification();
  EXPECT_TRUE(schemes.gotoItem(kPrivate).good());
}

TEST_F(SrSample, MissingSegSeriesIsRefused) {
  ms::dicomout::SegmentRef seg = seg_;
  seg.series_instance_uid.clear();
  EXPECT_THROW(ms::dicomout::write_sr(results_, *source_, study_, seg, (dir_ / "noseg.dcm").string()), ms::Error);
}

// Runs a command, returns its exit status and output (stdout + stderr).
int run(const std::string& cmd, std::string& output) {
  output.clear();
  FILE* p = ::popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return -1;
  char b[4096];
  while (std::fgets(b, sizeof b, p)) output += b;
  return ::pclose(p);
}

bool have(const std::string& tool) { return std::system(("command -v " + tool + " >/dev/null 2>&1").c_str()) == 0; }

TEST_F(SrSample, DsrdumpParsesIt) {
  if (!have("dsrdump")) GTEST_SKIP() << "dsrdump (dcmtk) not installed";
  for (const Json& r : {results_, degraded(results_)}) {
    std::string out;
    const int rc = run("dsrdump -Ee " + write(r, "dsrdump"), out);
    EXPECT_EQ(rc, 0) << out;
    EXPECT_NE(out.find("Comprehensive 3D SR"), std::string::npos) << out;
    EXPECT_EQ(out.find("E: "), std::string::npos) << out;
  }
}

TEST_F(SrSample, DciodvfyReportsNoErrors) {
  if (!have("dciodvfy")) GTEST_SKIP() << "dciodvfy (dicom3tools) not installed";
  for (const Json& r : {results_, degraded(results_)}) {
    std::string out;
    run("dciodvfy -new " + write(r, "dciodvfy"), out);
    std::istringstream lines(out);
    std::string line, errors, warnings;
    while (std::getline(lines, line)) {
      if (line.find("Error") != std::string::npos) errors += line + "\n";
      // Expected: dciodvfy knows only the standard coding schemes.
      const bool private_scheme = line.find(kPrivate) != std::string::npos || line.find("CodingSchemeUID") != std::string::npos ||
                                  line.find("Coding Scheme UID") != std::string::npos;
      if (line.find("Warning") != std::string::npos && !private_scheme) warnings += line + "\n";
    }
    EXPECT_TRUE(errors.empty()) << errors << "\nfull output:\n" << out;
    EXPECT_TRUE(warnings.empty()) << "unexplained warnings:\n" << warnings;
    EXPECT_NE(out.find("Comprehensive3DSR"), std::string::npos) << out;  // it recognised the IOD
  }
}

}  // namespace
