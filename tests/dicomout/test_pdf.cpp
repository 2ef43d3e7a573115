// report.pdf (cairo) and its Encapsulated PDF Storage object, from a real
// run on sample_dicom/symmetric. Text checks read the PDF back with poppler's
// pdftotext and are skipped when it is absent (scripts/install-deps, OPTIONAL).
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include "core/json_text.h"
#include "dicomout/dicomout.h"
#include "io/volume_io.h"

namespace fs = std::filesystem;
using ms::Json;

namespace {

const std::string kSampleDicom = std::string(MANDISYM_SOURCE_DIR) + "/sample_dicom/symmetric/dicom";

struct CommandOutput {
  int status = -1;
  std::string text;
};

CommandOutput run(const std::string& command) {
  CommandOutput out;
  FILE* p = popen((command + " 2>&1").c_str(), "r");
  if (!p) return out;
  char buf[4096];
  while (std::size_t n = std::fread(buf, 1, sizeof buf, p)) out.text.append(buf, n);
  const int st = pclose(p);
  out.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return out;
}

bool have(const char* tool) { return run(std::string("command -v ") + tool).status == 0; }

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// One run of the binary on the sample, shared by both suites.
struct Sample {
  fs::path dir;
  Json results;
  std::vector<std::string> views;
  ms::DicomSource source;
  std::string error;  // why the sample is unusable, empty when fine
};

Sample& sample() {
  static Sample s = [] {
    Sample x;
    x.dir = fs::temp_directory_path() / ("mandisym_test_pdf_" + std::to_string(getpid()));
    fs::create_directories(x.dir);
    static struct Cleanup {  // MANDISYM_KEEP_TEST_OUTPUT=1 keeps the files for a look
      fs::path dir;
      ~Cleanup() {
        std::error_code ec;
        if (!std::getenv("MANDISYM_KEEP_TEST_OUTPUT")) fs::remove_all(dir, ec);
      }
    } cleanup{x.dir};
    const CommandOutput r = run(std::string("'") + MANDISYM_BINARY + "' run '" + kSampleDicom + "' -o '" + (x.dir / "run").string() + "' --quiet");
    if (r.status != 0 && r.status != 8) {
      x.error = "mandisym run exited " + std::to_string(r.status) + ": " + r.text;
      return x;
    }
    x.results = ms::parse_json(slurp(x.dir / "run" / "results.json"));
    for (const auto& e : fs::directory_iterator(x.dir / "run" / "qc"))
      if (e.path().extension() == ".png" && e.path().stem().string().rfind("view_", 0) == 0) x.views.push_back(e.path().string());
    std::sort(x.views.begin(), x.views.end());
    const auto scan = ms::io::read_scan(kSampleDicom);
    if (!scan.dicom) x.error = "read_scan gave no DICOM source";
    else x.source = *scan.dicom;
    return x;
  }();
  return s;
}

// Pages of a PDF: pdfinfo when installed, else the /Type /Page objects (not /Pages).
int page_count(const fs::path& pdf) {
  if (have("pdfinfo")) {
    const CommandOutput r = run("pdfinfo '" + pdf.string() + "'");
    const auto at = r.text.find("Pages:");
    return at == std::string::npos ? -1 : std::atoi(r.text.c_str() + at + 6);
  }
  const std::string bytes = slurp(pdf);
  int pages = 0;
  for (auto at = bytes.find("/Type /Page"); at != std::string::npos; at = bytes.find("/Type /Page", at + 1))
    if (at + 11 >= bytes.size() || bytes[at + 11] != 's') ++pages;
  return pages;
}

// The PDF's text with runs of white space made single spaces.
std::string pdf_text(const fs::path& pdf) {
  const CommandOutput r = run("pdftotext '" + pdf.string() + "' -");
  std::string out;
  for (char c : r.text) {
    const bool space = c == ' ' || c == '\n' || c == '\t' || c == '\f' || c == '\r';
    if (!space) out += c;
    else if (!out.empty() && out.back() != ' ') out += ' ';
  }
  return out;
}

std::string format3(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3f", v);
  return b;
}

// report.html's wording of a band (reports/interpretation.cpp).
std::string band_words(const std::string& band) {
  if (band == "typical") return "within typical range";
  if (band == "mild") return "mild asymmetry";
  if (band == "marked") return "marked asymmetry";
  return "not available";
}

class PdfReport : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { sample(); }
  void SetUp() override { ASSERT_TRUE(sample().error.empty()) << sample().error; }
  fs::path write(const Json& results, const std::string& name) {
    const fs::path pdf = sample().dir / name;
    ms::dicomout::write_report_pdf(results, sample().views, pdf.string());
    return pdf;
  }
};

TEST_F(PdfReport, StartsWithPdfHeaderAndHasTwoPages) {
  const fs::path pdf = write(sample().results, "report.pdf");
  EXPECT_EQ(slurp(pdf).substr(0, 5), "%PDF-");
  EXPECT_EQ(page_count(pdf), 2);
  EXPECT_FALSE(fs::exists(pdf.string() + ".partial"));
}

TEST_F(PdfReport, ShowsSafScoreWithItsBandAndTheViews) {
  if (!have("pdftotext")) GTEST_SKIP() << "pdftotext (poppler-utils) not installed";
  const Json& r = sample().results;
  ASSERT_TRUE(r["interpretation"]["saf_score"]["value"].is_number());
  const std::string text = pdf_text(write(r, "report.pdf"));
  EXPECT_NE(text.find("SAF asymmetry score"), std::string::npos) << text;
  EXPECT_NE(text.find(format3(r["interpretation"]["saf_score"]["value"].get<double>()) + " rad"), std::string::npos) << text;
  EXPECT_NE(text.find(band_words(r["interpretation"]["saf_score"]["band"].get<std::string>())), std::string::npos) << text;
  EXPECT_NE(text.find("Quality control"), std::string::npos);
  EXPECT_NE(text.find(r["input"]["series_uid"].get<std::string>().substr(0, 20)), std::string::npos);
  ASSERT_FALSE(sample().views.empty()) << "the sample run rendered no views";
  for (const auto& v : sample().views) {  // every caption, from the file name
    std::string caption = fs::path(v).stem().string().substr(5);
    std::replace(caption.begin(), caption.end(), '_', ' ');
    EXPECT_NE(text.find(caption), std::string::npos) << caption;
  }
}

TEST_F(PdfReport, QcFailShowsTheFailureAndNoHeadline) {
  if (!have("pdftotext")) GTEST_SKIP() << "pdftotext (poppler-utils) not installed";
  Json r = sample().results;
  r["qc"]["status"] = "fail";
  Json& check = r["qc"]["checks"][0];
  check["name"] = "forged_check_for_test";
  check["passed"] = false;
  check["severity"] = "fail";
  check["meaning"] = "forged by test_pdf";
  const fs::path pdf = write(r, "report_fail.pdf");
  const std::string text = pdf_text(pdf);
  EXPECT_NE(text.find("failed quality control"), std::string::npos) << text;
  EXPECT_NE(text.find("forged_check_for_test"), std::string::npos) << text;
  EXPECT_NE(text.find("forged by test_pdf"), std::string::npos) << text;
  EXPECT_EQ(text.find("Headline"), std::string::npos) << text;
  EXPECT_EQ(text.find("SAF asymmetry score"), std::string::npos) << text;
  EXPECT_EQ(text.find(band_words(r["interpretation"]["saf_score"]["band"].get<std::string>())), std::string::npos) << text;
  EXPECT_EQ(page_count(pdf), 2);
}

TEST_F(PdfReport, MissingValuesReadNotComputedNeverZero) {
  if (!have("pdftotext")) GTEST_SKIP() << "pdftotext (poppler-utils) not installed";
  Json r = sample().results;
  r["interpretation"]["saf_score"]["value"] = nullptr;
  r["interpretation"]["saf_score"]["band"] = "unavailable";
  r["scores"]["bilateral"]["ramus_height_mm"]["L"] = nullptr;
  const std::string text = pdf_text(write(r, "report_missing.pdf"));
  EXPECT_NE(text.find("SAF asymmetry score not computed"), std::string::npos) << text;
  EXPECT_EQ(text.find("0.000 rad"), std::string::npos) << text;
  EXPECT_NE(text.find("ramus height (mm) not computed"), std::string::npos) << text;
}

TEST_F(PdfReport, LongTextWrapsWithinThePage) {
  if (!have("pdftotext")) GTEST_SKIP() << "pdftotext (poppler-utils) not installed";
  Json r = sample().results;
  std::string warning = "START_OF_LONG_WARNING";
  for (int k = 0; k < 120; ++k) warning += " word" + std::to_string(k);
  warning += " " + std::string(150, 'X') + " END_OF_LONG_WARNING";
  r["warnings"].push_back(warning);
  const fs::path pdf = write(r, "report_long.pdf");
  const std::string text = pdf_text(pdf);
  EXPECT_NE(text.find("START_OF_LONG_WARNING"), std::string::npos);
  EXPECT_NE(text.find("word119"), std::string::npos);
  EXPECT_NE(text.find("END_OF_LONG_WARNING"), std::string::npos);
  // Nothing drawn beyond the right margin: pdftotext -x/-W crops to the text column.
  const CommandOutput cropped = run("pdftotext -x 0 -y 0 -W 560 -H 842 '" + pdf.string() + "' -");
  EXPECT_NE(cropped.text.find("END_OF_LONG_WARNING"), std::string::npos);
  const CommandOutput right = run("pdftotext -x 560 -y 0 -W 40 -H 842 '" + pdf.string() + "' -");
  EXPECT_EQ(right.text.find_first_not_of(" \n\f"), std::string::npos) << right.text;
}

class PdfEncapsulated : public PdfReport {};

TEST_F(PdfEncapsulated, ReadsBackWithThePdfBytesInTheSourceStudy) {
  const fs::path pdf = write(sample().results, "report.pdf");
  const auto study = ms::dicomout::read_study_context(sample().source, false, "test");
  const fs::path dcm = sample().dir / "report.dcm";
  const auto w = ms::dicomout::write_encapsulated_pdf(pdf.string(), sample().source, study, dcm.string());
  DcmFileFormat ff;
  ASSERT_TRUE(ff.loadFile(dcm.c_str()).good());
  DcmDataset& ds = *ff.getDataset();
  const Uint8* doc = nullptr;
  unsigned long n = 0;
  ASSERT_TRUE(ds.findAndGetUint8Array(DCM_EncapsulatedDocument, doc, &n).good());
  const std::string bytes = slurp(pdf);
  ASSERT_TRUE(n == bytes.size() || (n == bytes.size() + 1 && doc[n - 1] == 0)) << n << " vs " << bytes.size();
  EXPECT_EQ(n % 2, 0u);
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(doc), bytes.size()), bytes);
  Uint32 length = 0;
  EXPECT_TRUE(ds.findAndGetUint32(DCM_EncapsulatedDocumentLength, length).good());
  EXPECT_EQ(length, bytes.size());
  auto str = [&](const DcmTagKey& t) {
    OFString v;
    ds.findAndGetOFStringArray(t, v);
    return std::string(v.c_str());
  };
  EXPECT_EQ(str(DCM_SOPClassUID), UID_EncapsulatedPDFStorage);
  EXPECT_EQ(str(DCM_StudyInstanceUID), sample().source.study_uid);
  EXPECT_EQ(str(DCM_Modality), "DOC");
  EXPECT_EQ(str(DCM_SeriesNumber), "9703");
  EXPECT_EQ(str(DCM_SeriesDescription), "MandiSym report");
  EXPECT_EQ(str(DCM_MIMETypeOfEncapsulatedDocument), "application/pdf");
  EXPECT_EQ(str(DCM_BurnedInAnnotation), "YES");
  EXPECT_EQ(str(DCM_SOPInstanceUID), w.sop_instance_uid);
  EXPECT_EQ(str(DCM_SeriesInstanceUID), w.series_instance_uid);
  EXPECT_NE(str(DCM_SeriesInstanceUID), sample().source.series_uid);
  std::set<std::string> source_instances;
  for (const auto& f : sample().source.frames) source_instances.insert(f.sop_instance_uid);
  DcmSequenceOfItems* seq = nullptr;
  ASSERT_TRUE(ds.findAndGetSequence(DCM_SourceInstanceSequence, seq).good());
  std::set<std::string> referenced;
  for (unsigned long k = 0; k < seq->card(); ++k) {
    OFString uid;
    seq->getItem(k)->findAndGetOFString(DCM_ReferencedSOPInstanceUID, uid);
    referenced.insert(uid.c_str());
  }
  EXPECT_EQ(referenced, source_instances);
}

TEST_F(PdfEncapsulated, DciodvfyReportsNoErrors) {
  if (!have("dciodvfy")) GTEST_SKIP() << "dciodvfy (dicom3tools) not installed";
  const fs::path pdf = write(sample().results, "report.pdf");
  const auto study = ms::dicomout::read_study_context(sample().source, false, "test");
  const fs::path dcm = sample().dir / "report_vfy.dcm";
  ms::dicomout::write_encapsulated_pdf(pdf.string(), sample().source, study, dcm.string());
  const CommandOutput r = run("dciodvfy '" + dcm.string() + "'");
  ASSERT_NE(r.text.find("Encapsulated"), std::string::npos) << "dciodvfy did not recognise the IOD:\n" << r.text;
  std::istringstream lines(r.text);
  std::string line, errors;
  while (std::getline(lines, line))
    if (line.find("Error") != std::string::npos) errors += line + "\n";
  EXPECT_TRUE(errors.empty()) << errors;
  // Only the IOD's own attributes: not a Standard Extended SOP Class.
  EXPECT_EQ(r.text.find("not present in standard DICOM IOD"), std::string::npos) << r.text.substr(0, 2000);
}

}  // namespace
