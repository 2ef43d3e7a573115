// End to end: the mandisym binary on the bundled sample_dicom/ series.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <zlib.h>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <tuple>
#include <utility>

#include "core/array_order.h"
#include "core/json_text.h"
#include "io/itk_geometry.h"
#include "io/volume_io.h"
#include "surface/surface.h"

#include <itkBinShrinkImageFilter.h>
#include <itkDiscreteGaussianImageFilter.h>
#include <itkResampleImageFilter.h>
#include <itkVersorRigid3DTransform.h>

namespace fs = std::filesystem;
using Value = ms::Json;
using ms::json_numbers;
using ms::parse_json;

namespace {

const std::string kBin = MANDISYM_BINARY;
const fs::path kSamples = fs::path(MANDISYM_SOURCE_DIR) / "sample_dicom";

fs::path temp_dir(const std::string& name) {
  fs::path p = fs::temp_directory_path() / ("mandisym_e2e_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  return p;
}

// The run arguments of an OpenKBP scan (HU + 1000) as the tests run it,
// up to its output folder: append the folder (and any further options).
std::string openkbp_run_args(const fs::path& ct) {
  return "run " + ct.string() + " --hu-offset -1000 -q --no-figures --no-cranial -o ";
}

// Runs the binary; returns its exit code; stderr goes to err.
int run(const std::string& args, std::string* err = nullptr) {
  const fs::path errf = temp_dir("stderr.txt");
  const std::string cmd = kBin + " " + args + " > /dev/null 2> " + errf.string();
  const int st = std::system(cmd.c_str());
  if (err) {
    std::ifstream f(errf);
    std::stringstream s;
    s << f.rdbuf();
    *err = s.str();
  }
  fs::remove(errf);
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

// The real headsq scan from ../shared/data ("" when absent: the test skips).
// A file's bytes.
std::string slurp_file(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

fs::path headsq_nhdr() {
  const fs::path p = fs::path(MANDISYM_SHARED_DATA) / "headsq" / "quarter.nhdr";
  return fs::exists(p) ? p : fs::path();
}

Value load(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return parse_json(s.str());
}

// The bytes of a gzip file ("" when it cannot be read).
std::string gunzip(const fs::path& p) {
  std::string out;
  gzFile f = gzopen(p.c_str(), "rb");
  if (!f) return out;
  char buf[65536];
  for (int n; (n = gzread(f, buf, sizeof buf)) > 0;) out.append(buf, static_cast<std::size_t>(n));
  gzclose(f);
  return out;
}

// Offset of a NIfTI-1 file's voxels (its header's vox_offset).
std::size_t nifti_voxel_offset(const std::string& nii) {
  float vox_offset = 0;
  if (nii.size() >= 352) std::memcpy(&vox_offset, nii.data() + 108, 4);
  return static_cast<std::size_t>(vox_offset);
}

// Dice of two NIfTI masks on one grid, read as ingest reads them (canonical
// array order: the files may store their voxels in different orders);
// -1 when the grids differ.
double nifti_mask_dice(const fs::path& a, const fs::path& b) {
  const ms::Mask x = ms::io::read_mask(a.string()), y = ms::io::read_mask(b.string());
  if (!x.geom.same_grid(y.geom, 1e-3)) return -1;
  return ms::dice(x, y);
}

// The folder of a sample's shared run (results()).
fs::path sample_run_dir(const std::string& sample) {
  return fs::temp_directory_path() / ("mandisym_e2e_run_" + sample + "_" + std::to_string(::getpid()));
}

// The region where the SAF map is larger on one side (largest of the
// lateral map's regional means), checked against the summary results.json gives.
std::string largest_sided_region(const Value& saf) {
  std::string name;
  double best = -1e30;
  for (const auto& [n, v] : saf.at("regions_lateral").items())
    if (v.get<double>() > best) best = v.get<double>(), name = n;
  EXPECT_EQ(saf.at("largest_region_sided").get<std::string>(), name);
  return name;
}

// One run per sample, shared by the tests below.
const Value& results(const std::string& sample) {
  static std::map<std::string, Value> cache;
  auto it = cache.find(sample);
  if (it != cache.end()) return it->second;
  const fs::path out = sample_run_dir(sample);
  fs::remove_all(out);
  const int code = run("run " + (kSamples / sample / "dicom").string() + " -o " + out.string() + " --quiet");
  EXPECT_EQ(code, 0) << sample;
  Value v = fs::exists(out / "results.json") ? load(out / "results.json") : Value();
  return cache[sample] = v;
}

}  // namespace

TEST(EndToEnd, WritesEveryOutputOfTheContract) {
  const fs::path out = temp_dir("files");
  ASSERT_EQ(run("run " + (kSamples / "symmetric" / "dicom").string() + " -o " + out.string() + " -q"), 0);
  for (const char* f : {"report.html", "results.json", "mandible_mask.nii.gz", "mandible.vtp", "mandible.stl",
                        "landmarks.mrk.json", "symmetry_plane.mrk.json", "log.txt", "results.csv", "srd.json", "report.pdf"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  EXPECT_TRUE(fs::is_directory(out / "qc"));
  // No staging leftovers.
  for (const auto& e : fs::directory_iterator(out))
    EXPECT_EQ(e.path().filename().string().find(".mandisym-partial"), std::string::npos);
  const Value lm = load(out / "landmarks.mrk.json");
  EXPECT_EQ(lm.at("markups")[0].at("coordinateSystem").get<std::string>(), "LPS");
  EXPECT_EQ(lm.at("markups")[0].at("controlPoints").size(), 8u);
  const Value pl = load(out / "symmetry_plane.mrk.json");
  EXPECT_EQ(pl.at("markups")[0].at("type").get<std::string>(), "Plane");
  // The sample holds the skull base and vault above the condyles: the cranial
  // plane is fitted, and on this symmetric head it is the mandible's plane.
  const Value cp = load(out / "cranial_plane.mrk.json");
  EXPECT_EQ(cp.at("markups")[0].at("controlPoints")[0].at("label").get<std::string>(), "cranial mid-sagittal plane");
  const Value cranial = load(out / "results.json").at("cranial_plane");
  ASSERT_TRUE(cranial.is_object());
  EXPECT_LT(cranial.at("angle_to_mandible_plane_deg").get<double>(), 0.5);
  EXPECT_GT(cranial.at("bone_volume_cm3").get<double>(), 50);
  EXPECT_LT(std::abs(cranial.at("to_cranial_plane_mm").at("Me").get<double>()), 1.0);
  // SRD descriptors at every landmark; on the symmetric sample each twin
  // matches its bin-reversed partner far better than as it is (chirality).
  const Value srd = load(out / "srd.json");
  const std::size_t bins = static_cast<std::size_t>(srd.at("bins").get<double>());
  const std::size_t rings = static_cast<std::size_t>(srd.at("rings").get<double>());
  EXPECT_EQ(srd.at("landmarks").size(), 8u);
  EXPECT_EQ(srd.at("landmarks").at("Co_L")[0].at("histogram").size(), bins * rings);
  const Value twins = load(out / "results.json").at("scores").at("saf").at("srd");
  for (const char* n : {"Co_L", "Cr_L", "Go_L", "Me", "Pog"}) {
    const Value& t = twins.at(n);
    EXPECT_LT(t.at("mirror_mismatch_rad").get<double>(), 0.5 * t.at("handedness_rad").get<double>()) << n;
  }
  EXPECT_EQ(twins.at("Co_L").at("twin").get<std::string>(), "Co_R");
  std::ifstream html(out / "report.html");
  std::stringstream s;
  s << html.rdbuf();
  EXPECT_EQ(s.str().find("http://"), std::string::npos);  // self-contained
  EXPECT_NE(s.str().find("data:image/png;base64,"), std::string::npos);
  fs::remove_all(out);
}

TEST(EndToEnd, ResultsJsonHasEveryKeyOfOutputsMd) {
  const Value& r = results("symmetric");
  ASSERT_TRUE(r.is_object());
  const std::map<std::string, std::vector<std::string>> required = {
      {"", {"schema_version", "tool", "input", "segmentation", "mesh", "landmarks", "symmetry_plane", "scores",
            "timings_s", "warnings"}},
      {"tool", {"name", "version"}},
      {"input", {"path", "kind", "series_uid", "modality", "size_voxels", "spacing_mm", "sha256_of_pixel_data"}},
      {"segmentation", {"method", "voxels", "volume_mm3", "truncated"}},
      {"mesh", {"vertices", "faces", "area_mm2", "volume_mm3", "genus", "closed"}},
      {"landmarks", {"Co_L", "Co_R", "Cr_L", "Cr_R", "Go_L", "Go_R", "Me", "Pog"}},
      {"symmetry_plane", {"point", "normal", "rms_landmark_residual_mm"}},
      {"scores", {"saf", "mirror", "bilateral"}},
      {"timings_s", {"total"}},
  };
  for (const auto& [section, keys] : required) {
    const Value& obj = section.empty() ? r : r.at(section);
    for (const auto& k : keys) EXPECT_TRUE(obj.contains(k)) << section << "." << k;
  }
  const Value& s = r.at("scores");
  for (const char* k : {"score", "per_configuration", "regions"}) EXPECT_TRUE(s.at("saf").contains(k)) << k;
  for (const char* k : {"mean_mm", "signed_mean_mm", "rms_mm", "p95_mm", "max_mm", "pct_area_over_1mm",
                        "pct_area_over_2mm", "regions"})
    EXPECT_TRUE(s.at("mirror").contains(k)) << k;
  for (const char* k : {"ramus_height_mm", "body_length_mm", "gonial_angle_deg"})
    for (const char* side : {"L", "R", "diff"}) EXPECT_TRUE(s.at("bilateral").at(k).contains(side)) << k << side;
  EXPECT_EQ(r.at("schema_version").get<std::string>(), "1.0");
  EXPECT_EQ(r.at("input").at("kind").get<std::string>(), "dicom");
  EXPECT_EQ(r.at("input").at("modality").get<std::string>(), "CT");
  EXPECT_TRUE(r.at("mesh").at("closed").get<bool>());
  // The sample's teeth touch their neighbours: 4 handles, removed by the
  // plugs of a 1 mm closing (never the whole closing), so the surface is genus 0.
  EXPECT_EQ(r.at("mesh").at("genus").get<double>(), 0.0);
  EXPECT_NE(r.at("mesh").at("closing_scope").get<std::string>(), "everywhere");
  // What the automatic segmentation used (the sample is calibrated, so the offset is small).
  EXPECT_LT(std::abs(r.at("segmentation").at("calibration_offset_hu").get<double>()), 20.0);
  EXPECT_GT(r.at("segmentation").at("separation_depth_mm").get<double>(), 0.0);
  for (const auto& n : {"Co_L", "Me"}) EXPECT_EQ(r.at("landmarks").at(n).size(), 3u);
  // Interpretation bands (docs/report.md): the symmetric sample is typical on every banded number.
  for (const char* k : {"saf_score", "mirror_distance", "ramus_height", "menton_deviation"}) {
    const Value& b = r.at("interpretation").at(k);
    EXPECT_EQ(b.at("band").get<std::string>(), "typical") << k;
    EXPECT_TRUE(b.at("value").is_number()) << k;
  }
  EXPECT_TRUE(r.at("interpretation").at("saf_score").at("provisional").get<bool>());
}

TEST(EndToEnd, SymmetricSampleMatchesItsGroundTruthPlane) {
  const Value& r = results("symmetric");
  const Value gt = load(kSamples / "symmetric" / "ground_truth" / "symmetry_plane.json");
  double cosang = 0;
  for (std::size_t a = 0; a < 3; ++a)
    cosang += r.at("symmetry_plane").at("normal")[a].get<double>() * gt.at("normal")[a].get<double>();
  EXPECT_GT(cosang, std::cos(1.0 * 3.14159265 / 180));  // within 1 degree
  double off = 0;
  for (std::size_t a = 0; a < 3; ++a)
    off += (r.at("symmetry_plane").at("point")[a].get<double>() - gt.at("point")[a].get<double>()) * gt.at("normal")[a].get<double>();
  EXPECT_LT(std::abs(off), 0.5);
  EXPECT_LT(r.at("scores").at("mirror").at("mean_mm").get<double>(), 0.3);
}

TEST(EndToEnd, AsymmetricSampleScoresHigherOnSafAndMirrorDistance) {
  const Value& sym = results("symmetric");
  const Value& asym = results("ramus_L_plus4mm");
  ASSERT_TRUE(sym.is_object());
  ASSERT_TRUE(asym.is_object());
  const double saf_s = sym.at("scores").at("saf").at("score").get<double>();
  const double saf_a = asym.at("scores").at("saf").at("score").get<double>();
  EXPECT_GT(saf_a, saf_s);
  const double mir_s = sym.at("scores").at("mirror").at("rms_mm").get<double>();
  const double mir_a = asym.at("scores").at("mirror").at("rms_mm").get<double>();
  EXPECT_GT(mir_a, mir_s + 0.2);
  // The left ramus is the longer one, by roughly the imposed amount.
  const double diff = asym.at("scores").at("bilateral").at("ramus_height_mm").at("diff").get<double>();
  EXPECT_GT(diff, 2.0);
  EXPECT_LT(diff, 6.0);
  const double sym_diff = sym.at("scores").at("bilateral").at("ramus_height_mm").at("diff").get<double>();
  EXPECT_LT(std::abs(sym_diff), 1.0);
  // The sided SAF map points to the longer side (METHOD.md §7): its largest
  // regional mean is the left condyle (measured 0.076 against 0.045 on the
  // right; the symmetrised map's own regions are 0.057 / 0.062, no side).
  EXPECT_EQ(largest_sided_region(asym.at("scores").at("saf")), "condyle_L");
  // The same region in the headline CSV's last column.
  std::ifstream csv(sample_run_dir("ramus_L_plus4mm") / "results.csv");
  std::string header, row;
  std::getline(csv, header);
  std::getline(csv, row);
  EXPECT_EQ(header.substr(header.rfind(',') + 1), "saf_largest_region_sided");
  EXPECT_EQ(row.substr(row.rfind(',') + 1), "\"condyle_L\"");
}

// The SAF score is defined at 1 mm edges: a surface meshed at 2 mm is scored
// on a 1 mm remeshing of itself. Measured on this sample: 0.02173 at 1 mm,
// 0.02234 at 2 mm (+2.8 %; from the mask alone 0.02149 and 0.02251, and
// scored on the 2 mm mesh itself 0.02693, +25 %). The VTP still carries the
// map on the 2 mm mesh's own vertices.
TEST(EndToEnd, SafScoreBarelyMovesWithTheEdgeLength) {
  const Value& fine = results("ramus_L_plus4mm");
  ASSERT_TRUE(fine.is_object());
  const fs::path out = temp_dir("edge2");
  std::string err;
  ASSERT_EQ(run("run " + (kSamples / "ramus_L_plus4mm" / "dicom").string() + " -o " + out.string() +
                    " -q --no-figures --no-cranial --edge-length 2",
                &err),
            0)
      << err;
  const Value coarse = load(out / "results.json");
  EXPECT_LT(coarse.at("mesh").at("faces").get<double>(), 0.4 * fine.at("mesh").at("faces").get<double>());
  const double a = fine.at("scores").at("saf").at("score").get<double>();
  const double b = coarse.at("scores").at("saf").at("score").get<double>();
  RecordProperty("saf_1mm_vs_2mm", std::to_string(a) + " " + std::to_string(b));
  EXPECT_NEAR(b / a, 1.0, 0.08);
  // The map on the output mesh: one value per vertex, not all zero.
  EXPECT_GT(coarse.at("scores").at("saf").at("regions").size(), 0u);
  fs::remove_all(out);
}

TEST(EndToEnd, MissingInputExitsWithCode3AndWritesNothing) {
  const fs::path out = temp_dir("missing");
  std::string err;
  EXPECT_EQ(run("run /nonexistent/scan -o " + out.string(), &err), 3);
  EXPECT_NE(err.find("/nonexistent/scan"), std::string::npos);
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;  // one line
  EXPECT_FALSE(fs::exists(out / "results.json"));
}

TEST(EndToEnd, NonDicomFolderExitsWithCode4) {
  const fs::path in = temp_dir("junk_in"), out = temp_dir("junk_out");
  fs::create_directories(in);
  std::ofstream(in / "a.dcm") << "this is not DICOM";
  std::string err;
  EXPECT_EQ(run("run " + in.string() + " -o " + out.string(), &err), 4);
  EXPECT_FALSE(fs::exists(out / "results.json"));
  EXPECT_FALSE(fs::exists(out / "report.html"));
  fs::remove_all(in);
}

TEST(EndToEnd, UsageErrorsExitWithCode2) {
  EXPECT_EQ(run("run"), 2);
  EXPECT_EQ(run("frobnicate"), 2);
  EXPECT_EQ(run("run x -o y --no-such-option"), 2);
  EXPECT_EQ(run("phantom -o /tmp/x --noise abc"), 2);
}

// A stage that fails after the segmentation, while the mask file and QC
// slices are still being written on the second thread: one line, the
// documented exit code, and no output folder left behind (the background
// job must finish before the mask it reads and the staging folder go).
TEST(EndToEnd, FailureAfterSegmentationLeavesNothing) {
  const fs::path ph = temp_dir("onevox_phantom"), out = temp_dir("onevox_out");
  ASSERT_EQ(run("phantom -o " + ph.string() + " --spacing 2 --fov 120,110,110 --seed 5 --no-preview"), 0);
  // The ground-truth mask (same grid as the CT) with a single voxel left:
  // segmentation accepts it, the surface stage then has nothing to contour.
  std::string nii = gunzip(ph / "ground_truth" / "mandible_mask.nii.gz");
  ASSERT_GT(nii.size(), 352u);
  const std::size_t start = nifti_voxel_offset(nii);
  ASSERT_LT(start, nii.size());
  std::fill(nii.begin() + static_cast<std::ptrdiff_t>(start), nii.end(), '\0');
  nii[start + (nii.size() - start) / 2] = 1;
  const fs::path mask = ph / "one_voxel.nii";
  std::ofstream(mask, std::ios::binary) << nii;
  std::string err;
  EXPECT_EQ(run("run " + (ph / "dicom").string() + " --mask " + mask.string() + " -o " + out.string(), &err), 6) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_FALSE(fs::exists(out)) << "a failed run left its output folder";
  fs::remove_all(ph);
}

// A head 30 mm off centre: the scan's side cuts away the left condyle,
// coronoid and angle. Nothing can be mirrored, so the run stops with exit 6
// and one line that says why, and writes nothing; 15 mm off centre (the left
// ramus cut at its condyle, Cr_L and Go_L inside) it completes with the
// truncation flagged and scores withheld. (At 20 mm the angle's lateral
// surface is within 4 mm of the cut, so Go_L is missing too and the run
// stops as at 30 mm; the extreme point along the bisector used to give a
// Go_L there, 15 mm from the phantom's.)
TEST(EndToEnd, HeadCutBySideOfTheScanStopsOrWarns) {
  const fs::path ph = temp_dir("cut_phantom"), out = temp_dir("cut_out");
  ASSERT_EQ(run("phantom -o " + ph.string() + " --spacing 1.5 --shift 30,0,0 --no-preview"), 0);
  std::string err;
  EXPECT_EQ(run("run " + (ph / "dicom").string() + " -o " + out.string() + " -q --no-figures --no-cranial", &err), 6) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_NE(err.find("cut by the scan's edge (Co_L, Cr_L, Go_L missing)"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(out));
  fs::remove_all(ph);
  ASSERT_EQ(run("phantom -o " + ph.string() + " --spacing 1.5 --shift 15,0,0 --no-preview"), 0);
  ASSERT_EQ(run("run " + (ph / "dicom").string() + " -o " + out.string() + " -q --no-figures --no-cranial", &err), 0) << err;
  const Value r = load(out / "results.json");
  EXPECT_TRUE(r.at("segmentation").at("truncated").get<bool>());
  ASSERT_EQ(r.at("segmentation").at("truncated_at").size(), 1u);  // the head moved 15 mm to its left
  EXPECT_EQ(r.at("segmentation").at("truncated_at")[0].get<std::string>(), "left side");
  EXPECT_TRUE(r.at("scores").at("saf").at("score").is_null());
  EXPECT_TRUE(r.at("landmarks").at("Co_L").is_null());
  EXPECT_FALSE(r.at("landmarks").at("Go_L").is_null());
  EXPECT_GT(r.at("segmentation").at("volume_mm3").get<double>(), 85000.0);  // 92.6 cm3 in the scan
  fs::remove_all(ph);
  fs::remove_all(out);
}

// A run killed mid-way (SIGKILL: no clean-up runs) leaves its hidden staging
// folder; the next run into the same folder removes it, because its marker's
// lock died with it (docs/security.md, "Output folder"). A folder that only
// looks like an old staging folder (no marker) is left alone.
TEST(EndToEnd, NextRunRemovesStagingFoldersOfKilledRuns) {
  const fs::path out = temp_dir("stale_out");
  const fs::path decoy = out / ".mandisym-partial-999999999";
  fs::create_directories(decoy);
  std::ofstream(decoy / "notes.txt") << "a user's folder";
  const std::string series = (kSamples / "symmetric" / "dicom").string();
  // Start a run, wait for its staging folder (with marker), kill it.
  const std::string killer = "bash -c '" + kBin + " run " + series + " -o " + out.string() +
                             " -q --no-figures --no-cranial & p=$!; for i in $(seq 600); do "
                             "ls " + out.string() + "/.mandisym-partial-*-*/.mandisym-staging >/dev/null 2>&1 && break; sleep 0.05; done; "
                             "kill -9 $p; wait $p 2>/dev/null; true'";
  ASSERT_EQ(std::system(killer.c_str()), 0);
  std::vector<fs::path> left;
  for (const auto& e : fs::directory_iterator(out))
    if (e.path() != decoy && e.path().filename().string().rfind(".mandisym-partial-", 0) == 0) left.push_back(e.path());
  ASSERT_EQ(left.size(), 1u) << "the killed run left no staging folder";
  std::string err;
  ASSERT_EQ(run("run " + series + " -o " + out.string() + " --no-figures --no-cranial -q", &err), 0) << err;
  EXPECT_TRUE(fs::exists(out / "results.json"));
  EXPECT_FALSE(fs::exists(left[0])) << "the killed run's staging folder is still there";
  EXPECT_TRUE(fs::exists(decoy / "notes.txt")) << "a folder without a staging marker was removed";
  fs::remove_all(out);
}

// METHOD.md §7's symmetry-flip test, end to end: the same scan flipped
// left<->right swaps every _L/_R and leaves every score unchanged within 1 %.
// The flipped scan segments to the flipped mask and meshes to the mirror image
// of the same mesh (the surface's canonical orientation); measured on this
// phantom SAF 0.01078 both ways (it was 0.01078 / 0.01120, 3.9 %, before).
TEST(EndToEnd, MirroredScanSwapsTheSidesAndKeepsTheScores) {
  const fs::path ph = temp_dir("flip_phantoms");
  Value r[2];
  for (int m = 0; m < 2; ++m) {
    const fs::path in = ph / (m ? "mirrored" : "as_is"), out = ph / (m ? "out_mirrored" : "out_as_is");
    ASSERT_EQ(run("phantom -o " + in.string() + " --spacing 1 --yaw 8 --pitch 6 --roll -5 --ramus-L 2 --no-preview" +
                  (m ? " --mirror" : "")),
              0);
    std::string err;
    ASSERT_EQ(run("run " + (in / "dicom").string() + " -o " + out.string() + " -q --no-figures --no-cranial", &err), 0) << err;
    r[m] = load(out / "results.json");
  }
  const Value &a = r[0].at("scores"), &b = r[1].at("scores");
  const double sa = a.at("saf").at("score").get<double>(), sb = b.at("saf").at("score").get<double>();
  RecordProperty("saf_as_is_vs_mirrored", std::to_string(sa) + " " + std::to_string(sb));
  EXPECT_NEAR(sb, sa, 0.01 * sa);
  const double da = a.at("mirror").at("mean_mm").get<double>(), db = b.at("mirror").at("mean_mm").get<double>();
  EXPECT_NEAR(db, da, 0.01 * da);
  // L - R swaps sign: the longer ramus is the left one, then the right one.
  const double ra = a.at("bilateral").at("ramus_height_mm").at("diff").get<double>();
  const double rb = b.at("bilateral").at("ramus_height_mm").at("diff").get<double>();
  EXPECT_GT(ra, 1.0);
  EXPECT_NEAR(rb, -ra, 0.01 * ra);
  EXPECT_EQ(r[0].at("mesh").at("vertices").get<double>(), r[1].at("mesh").at("vertices").get<double>());
  // The sided SAF map points to the changed side in both.
  EXPECT_EQ(largest_sided_region(a.at("saf")), "condyle_L");
  EXPECT_EQ(largest_sided_region(b.at("saf")), "condyle_R");
  fs::remove_all(ph);
}

TEST(EndToEnd, PhantomVerbWritesReadableSeriesAndGroundTruth) {
  const fs::path out = temp_dir("phantom");
  ASSERT_EQ(run("phantom -o " + out.string() + " --spacing 2 --fov 120,110,110 --seed 5 --ramus-R 3 --no-preview"), 0);
  const Value lm = load(out / "ground_truth" / "landmarks.json");
  EXPECT_EQ(lm.at("coordinate_system").get<std::string>(), "LPS");
  EXPECT_EQ(lm.at("landmarks").size(), 8u);
  const Value asym = load(out / "ground_truth" / "asymmetry.json");
  EXPECT_EQ(asym.at("right").at("ramus_height_mm").get<double>(), 3.0);
  EXPECT_TRUE(fs::exists(out / "ground_truth" / "mandible_mask.nii.gz"));
  std::size_t n = 0;
  for (const auto& e : fs::directory_iterator(out / "dicom")) n += e.path().extension() == ".dcm";
  EXPECT_EQ(n, 55u);  // 110 mm / 2 mm slices
  fs::remove_all(out);
}

// Runs headsq (HU + 1024; the caller skips when headsq_nhdr() is empty) with
// extra options into a new folder; empty when the exit code is not the expected one (failed).
fs::path run_headsq(const std::string& options, const std::string& name, int expected_exit, std::string* err) {
  const fs::path nhdr = headsq_nhdr();
  const fs::path out = temp_dir(name);
  const int code = run("run " + nhdr.string() + " --hu-offset -1024 " + options + " -o " + out.string() + " -q", err);
  EXPECT_EQ(code, expected_exit) << *err;
  return code == expected_exit ? out : fs::path();
}

// headsq read as stored (no --orientation): the head is upside down in LPS.
// The run completes, writes everything, and fails quality control naming
// the orientation (exit 8; docs/qc.md): the atlas fits it better flipped.
TEST(EndToEnd, HeadsqUpsideDownFailsQualityControlNamingTheOrientation) {
  if (headsq_nhdr().empty()) GTEST_SKIP() << "shared data not present";
  std::string err;
  const fs::path out = run_headsq("", "headsq", 8, &err);
  if (out.empty()) return;
  EXPECT_NE(err.find("--orientation"), std::string::npos) << err;
  const Value r = load(out / "results.json");
  EXPECT_EQ(r.at("input").at("kind").get<std::string>(), "nrrd");
  EXPECT_EQ(r.at("input").at("size_voxels")[2].get<double>(), 93);
  EXPECT_EQ(r.at("qc").at("status").get<std::string>(), "fail");
  bool orientation_failed = false;
  for (std::size_t i = 0; i < r.at("qc").at("checks").size(); ++i) {
    const Value& c = r.at("qc").at("checks")[i];
    if (c.at("name").get<std::string>() == "orientation_margin") orientation_failed = !c.at("passed").get<bool>();
  }
  EXPECT_TRUE(orientation_failed);
  // The file carries no anatomical orientation: the run must say so.
  bool warned = false;
  for (std::size_t i = 0; i < r.at("warnings").size(); ++i)
    warned |= r.at("warnings")[i].get<std::string>().find("not anatomical") != std::string::npos;
  EXPECT_TRUE(warned);
  // The report opens with the failure and shows no headline.
  std::ifstream in(out / "report.html");
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(html.find("failed quality control"), std::string::npos);
  EXPECT_EQ(html.find("<h2>Headline</h2>"), std::string::npos);
  fs::remove_all(out);
}

// headsq upright but read without its --hu-offset: stored as HU + 1024, its
// air reads 0 HU and soft tissue ~1070, so the bone threshold takes soft
// tissue too (a 157 cm3 mask, Dice 0.53 against the reference, exit 0 with
// warnings before the input check). It fails quality control on its input
// (exit 8) and the message names the option that fixes it.
TEST(EndToEnd, HeadsqWithoutItsHuOffsetFailsNamingTheOffset) {
  const fs::path nhdr = headsq_nhdr();
  if (nhdr.empty()) GTEST_SKIP() << "shared data not present";
  const fs::path out = temp_dir("headsq_no_offset");
  std::string err;
  ASSERT_EQ(run("run " + nhdr.string() + " --orientation LPI --no-figures -o " + out.string() + " -q", &err), 8) << err;
  EXPECT_NE(err.find("--hu-offset -1024"), std::string::npos) << err;
  EXPECT_NE(err.find("lowest_value_hu"), std::string::npos) << err;
  const Value r = load(out / "results.json");
  EXPECT_EQ(r.at("qc").at("status").get<std::string>(), "fail");
  fs::remove_all(out);
}

// headsq upright (--orientation LPI): the mandible, and QC does not fail.
TEST(EndToEnd, HeadsqUprightIsTheMandibleAndPassesTheGate) {
  if (headsq_nhdr().empty()) GTEST_SKIP() << "shared data not present";
  std::string err;
  const fs::path out = run_headsq("--orientation LPI", "headsq_lpi", 0, &err);
  if (out.empty()) return;
  const Value r = load(out / "results.json");
  // 3.2 x 3.2 x 1.5 mm: an adult mandible with teeth is ~60-120 cm3 (the whole skull would be several hundred).
  const double cm3 = r.at("segmentation").at("volume_mm3").get<double>() / 1000;
  RecordProperty("headsq_mandible_cm3", std::to_string(cm3));
  EXPECT_GT(cm3, 50.0);
  EXPECT_LT(cm3, 130.0);
  EXPECT_TRUE(r.at("segmentation").at("atlas").at("found").get<bool>());
  EXPECT_NE(r.at("qc").at("status").get<std::string>(), "fail");
  // 3.2 mm voxels do not resolve the cortex: the surface follows the mask alone.
  EXPECT_EQ(r.at("parameters").at("surface_guide_level_hu").get<std::string>(), "none");
  // Against the reference made on its slices independently of the pipeline
  // (scripts/reference-headsq, docs/reference-headsq.md). Measured: Dice
  // 0.976; Co 3.1 / 1.5, Cr 0.7 / 1.9, Go 2.4 / 3.4, Me 1.2, Pog 1.3 mm,
  // each within 3 mm plus the reference's own uncertainty (Cr 2.5, Go 4,
  // Me 2, Pog 5 mm at these voxels); condylion within the reference's 3 mm
  // plus a sixth of a 3.2 mm pixel: before the condyles' tops were let up to
  // the joint space (docs/segmentation.md, step 3) Co_R was 3.9 mm off. Before the zone's rim
  // (docs/segmentation.md, step 3) Go_L was 10.9 mm off: the zone missed
  // the left ramus's posterior border by 1-2 voxels, so the posterior
  // tangent ran a voxel forward, and Dice was 0.964.
  const fs::path ref_dir = fs::path(MANDISYM_SOURCE_DIR) / "tests" / "data" / "headsq";
  const double dice = nifti_mask_dice(out / "mandible_mask.nii.gz", ref_dir / "reference_mask.nii.gz");
  std::printf("headsq: Dice %.3f against the reference\n", dice);
  EXPECT_GE(dice, 0.93);
  const Value ref = load(ref_dir / "reference_landmarks.json").at("landmarks");
  for (const auto& [l, tol] :
       std::map<std::string, double>{{"Co_L", 3.5}, {"Co_R", 3.5}, {"Cr_L", 5.5}, {"Cr_R", 5.5}, {"Go_L", 7}, {"Go_R", 7}, {"Me", 5}, {"Pog", 8}}) {
    const Value& p = r.at("landmarks").at(l);
    ASSERT_FALSE(p.is_null()) << l;
    double d2 = 0;
    for (std::size_t a = 0; a < 3; ++a) d2 += std::pow(p[a].get<double>() - ref.at(l)[a].get<double>(), 2);
    std::printf("headsq %s %.1f mm from the reference\n", l.c_str(), std::sqrt(d2));
    EXPECT_LE(std::sqrt(d2), tol) << l;
  }
  fs::remove_all(out);
}

// The Visible Human female head (1 mm, real, never tuned on) as a new user
// runs it: all 8 landmarks, a SAF score, QC pass, and the landmarks within
// 3 mm of the reference picked on its slices independently of the pipeline
// (tests/data/visible-human-female, docs/reference-vhf.md). Before the
// nasal floor was searched under mucosa too and the zone was cut at the
// joints: Pog 10.0, Co_R 4.9 mm; before gonion followed the bisector to the
// outline (the reference's construction) rather than taking the extreme
// point along it on this flattened angle: Go_R 3.8 mm.
TEST(EndToEnd, VisibleHumanFemaleLandmarksMatchTheReference) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "visible-human-female" / "ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "shared data not present";
  const fs::path out = temp_dir("vhf_out");
  std::string err;
  ASSERT_EQ(run("run " + ct.string() + " -o " + out.string() + " -q --no-figures --no-cranial", &err), 0) << err;
  const Value r = load(out / "results.json");
  const Value ref = load(fs::path(MANDISYM_SOURCE_DIR) / "tests" / "data" / "visible-human-female" / "reference_landmarks.json").at("landmarks");
  EXPECT_EQ(r.at("qc").at("status").get<std::string>(), "pass");
  EXPECT_TRUE(r.at("scores").at("saf").at("score").is_number());
  EXPECT_EQ(r.at("head_frame").at("source").get<std::string>(), "palatal plane");
  for (const char* l : {"Co_L", "Co_R", "Cr_L", "Cr_R", "Go_L", "Go_R", "Me", "Pog"}) {
    const Value& p = r.at("landmarks").at(l);
    ASSERT_FALSE(p.is_null()) << l << " missing";
    double d2 = 0;
    for (std::size_t a = 0; a < 3; ++a) d2 += std::pow(p[a].get<double>() - ref.at(l)[a].get<double>(), 2);
    const double d = std::sqrt(d2);
    std::printf("%s %.1f mm from the reference\n", l, d);
    EXPECT_LE(d, 3.0) << l;
  }
  fs::remove_all(out);
}

// The volume turned by deg about its grid's axis (0 i, 1 j, 2 k) through its
// centre, linear interpolation, air outside, rounded to whole HU as a stored
// scan is (ITK's ResampleImageFilter): a resampling, as a re-posed or
// re-gridded scan is.
ms::Volume turned_about(const ms::Volume& v, int grid_axis, double deg) {
  using Image = itk::Image<float, 3>;
  const Image::Pointer in = ms::io::float_view(v);
  auto turn = itk::VersorRigid3DTransform<double>::New();
  itk::Point<double, 3> centre;
  in->TransformContinuousIndexToPhysicalPoint(
      itk::ContinuousIndex<double, 3>(std::array<double, 3>{0.5 * (v.geom.size[0] - 1.0), 0.5 * (v.geom.size[1] - 1.0),
                                                            0.5 * (v.geom.size[2] - 1.0)}.data()),
      centre);
  itk::Vector<double, 3> axis;
  for (int a = 0; a < 3; ++a) axis[a] = v.geom.direction[3 * a + grid_axis];
  turn->SetCenter(centre);
  turn->SetRotation(axis, deg * M_PI / 180.0);
  auto resample = itk::ResampleImageFilter<Image, Image>::New();
  resample->SetInput(in);
  resample->SetTransform(turn);
  resample->UseReferenceImageOn();
  resample->SetReferenceImage(in);
  resample->SetDefaultPixelValue(*std::min_element(v.hu.begin(), v.hu.end()));
  resample->Update();
  ms::Volume out;
  out.geom = v.geom;
  const float* p = resample->GetOutput()->GetBufferPointer();
  out.hu.resize(v.hu.size());
  std::transform(p, p + out.hu.size(), out.hu.begin(), [](float x) { return std::round(x); });
  return out;
}

// The volume with `slices` of air beyond both ends of its k axis, in the same
// world space: room for a head turned about a horizontal axis.
ms::Volume padded_along_k(const ms::Volume& v, std::size_t slices) {
  ms::Volume out;
  out.geom = v.geom;
  out.geom.size[2] += 2 * slices;
  out.geom.origin = v.geom.index_to_lps(0, 0, -static_cast<double>(slices));
  const float air = *std::min_element(v.hu.begin(), v.hu.end());
  out.hu.assign(out.geom.voxel_count(), air);
  const std::size_t plane = v.geom.size[0] * v.geom.size[1];
  std::copy(v.hu.begin(), v.hu.end(), out.hu.begin() + static_cast<std::ptrdiff_t>(slices * plane));
  return out;
}

// A landmark of a results.json, LPS mm.
ms::Vec3 landmark(const Value& r, const std::string& name) {
  const Value& p = r.at("landmarks").at(name);
  return ms::Vec3{p[0].get<double>(), p[1].get<double>(), p[2].get<double>()};
}

// Runs the openkbp-train scan ct (HU + 1000) and its copy, written to dir
// as NIfTI; returns both runs' results (null values when a run failed).
std::pair<Value, Value> run_scan_and_copy(const fs::path& ct, const ms::Volume& copy, const fs::path& dir) {
  fs::create_directories(dir);
  ms::io::write_volume(copy, (dir / "copy.nii.gz").string());
  std::string err;
  const std::string opts = " --hu-offset -1000 -q --no-figures -o ";
  if (run("run " + ct.string() + opts + (dir / "a").string(), &err) != 0 ||
      run("run " + (dir / "copy.nii.gz").string() + opts + (dir / "b").string(), &err) != 0) {
    ADD_FAILURE() << err;
    return {};
  }
  return {load(dir / "a" / "results.json"), load(dir / "b" / "results.json")};
}

// Writes the Visible Human female blurred by a Gaussian of sigma_mm (a
// softer reconstruction kernel; ITK's DiscreteGaussianImageFilter), rounded
// to whole HU, to dir/soft.nii.gz. False when the shared data is absent.
bool write_softer_vhf(const fs::path& dir, double sigma_mm) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "visible-human-female" / "ct.nii.gz";
  if (!fs::exists(ct)) return false;
  fs::create_directories(dir);
  using Image = itk::Image<float, 3>;
  const ms::Volume v = ms::io::read_scan(ct.string()).volume;
  auto blur = itk::DiscreteGaussianImageFilter<Image, Image>::New();
  blur->SetInput(ms::io::float_view(v));
  blur->SetUseImageSpacing(true);
  blur->SetVariance(sigma_mm * sigma_mm);
  blur->Update();
  ms::Volume soft;
  soft.geom = v.geom;
  const float* p = blur->GetOutput()->GetBufferPointer();
  soft.hu.resize(v.hu.size());
  std::transform(p, p + soft.hu.size(), soft.hu.begin(), [](float x) { return std::round(x); });
  ms::io::write_volume(soft, (dir / "soft.nii.gz").string());
  return true;
}

// The Visible Human female as a softer reconstruction kernel gives it: a
// Gaussian of 0.5 mm (FWHM 1.2 mm) over its 1 mm voxels (ITK's
// DiscreteGaussianImageFilter), rounded to whole HU. Its joints' anterior
// spaces then fill above the bone threshold, so each condylar head touches
// its articular eminence, and the zone's cut at the joints (docs/segmentation.md,
// step 4) flooded through the thin cortex alone: the neck, fatty marrow
// inside a thin shell, was a valley as shallow as the blurred joint, and the
// outer flood took the left head (condylion 10.1 mm off, QC pass). Flooded
// through the bone's body (the marrow the cortex encloses), the head stays
// with its ramus: every landmark within 3 mm of the reference.
TEST(EndToEnd, SofterKernelKeepsTheCondylesOnTheirRami) {
  const fs::path dir = temp_dir("vhf_soft");
  if (!write_softer_vhf(dir, 0.5)) GTEST_SKIP() << "shared data not present";
  std::string err;
  ASSERT_EQ(run("run " + (dir / "soft.nii.gz").string() + " -o " + (dir / "out").string() + " -q --no-figures --no-cranial", &err), 0)
      << err;
  const Value r = load(dir / "out" / "results.json");
  const Value ref = load(fs::path(MANDISYM_SOURCE_DIR) / "tests" / "data" / "visible-human-female" / "reference_landmarks.json").at("landmarks");
  EXPECT_NE(r.at("qc").at("status").get<std::string>(), "fail");
  for (const char* l : {"Co_L", "Co_R", "Cr_L", "Cr_R", "Go_L", "Go_R", "Me", "Pog"}) {
    ASSERT_FALSE(r.at("landmarks").at(l).is_null()) << l << " missing";
    const double d = ms::distance(landmark(r, l), ms::Vec3{ref.at(l)[0].get<double>(), ref.at(l)[1].get<double>(), ref.at(l)[2].get<double>()});
    std::printf("%s %.1f mm from the reference\n", l, d);
    EXPECT_LE(d, 3.0) << l;
  }
  fs::remove_all(dir);
}

// Blurred by 0.7 mm (FWHM 1.6 mm) the Visible Human female's image
// separation finds a mandible the atlas verifies, and it is taken; but its
// boundary lies inside the blurred thin cortex: 25 % less than the atlas's
// zone (Dice 0.84 between them), the coronoid tips 6 mm low. The two
// estimates disagree beyond observer variation, and QC says so (warn,
// image_agrees_with_zone; docs/qc.md) instead of passing.
TEST(EndToEnd, SoftestKernelWarnsThatTheImageAndTheZoneDisagree) {
  const fs::path dir = temp_dir("vhf_softest");
  if (!write_softer_vhf(dir, 0.7)) GTEST_SKIP() << "shared data not present";
  std::string err;
  ASSERT_EQ(run("run " + (dir / "soft.nii.gz").string() + " -o " + (dir / "out").string() + " -q --no-figures --no-cranial", &err), 0)
      << err;
  const Value r = load(dir / "out" / "results.json");
  EXPECT_EQ(r.at("qc").at("status").get<std::string>(), "warn");
  bool seen = false;
  for (const Value& c : r.at("qc").at("checks"))
    if (c.at("name").get<std::string>() == "image_agrees_with_zone") {
      seen = true;
      EXPECT_FALSE(c.at("passed").get<bool>());
      EXPECT_LT(c.at("value").get<double>(), 0.85);
    }
  EXPECT_TRUE(seen);
  fs::remove_all(dir);
}

// The head pitched 15 degrees (chin up, as in a neck extended on the table):
// the Visible Human female turned about its grid's left-right axis, air added
// above and below so that the head stays in the grid. Condylion is the top
// of the condyle, whatever point of it the geodesic extremity marks
// (docs/landmarks.md, step 3): here the right condyle's extremity lies 18 mm
// down its neck, and the highest point within one 10 mm ball of it was
// 11.3 mm below the original's condylion. The climb to the process's top
// brought it to 4.9 mm, and flooding the joint cut through the bone's body
// (docs/segmentation.md, step 4) to 0.3 mm: through the cortex alone the
// turned mask's cut left 2-3 mm of the condyle's top out.
TEST(EndToEnd, PitchedHeadKeepsItsLandmarks) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "visible-human-female" / "ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "shared data not present";
  const fs::path dir = temp_dir("vhf_pitched");
  fs::create_directories(dir);
  constexpr double kDeg = 15.0;
  const ms::Volume v = padded_along_k(ms::io::read_scan(ct.string()).volume, 40);
  ms::io::write_volume(turned_about(v, 0, kDeg), (dir / "pitched.nii.gz").string());
  std::string err;
  const std::string opts = " -q --no-figures --no-cranial -o ";
  ASSERT_EQ(run("run " + ct.string() + opts + (dir / "a").string(), &err), 0) << err;
  ASSERT_EQ(run("run " + (dir / "pitched.nii.gz").string() + opts + (dir / "b").string(), &err), 0) << err;
  const Value a = load(dir / "a" / "results.json"), b = load(dir / "b" / "results.json");
  // The copy's point q was the original's R (q - c) + c (ITK's resampling
  // transform, a rotation about the grid's first axis through its centre c).
  const ms::Vec3 c = v.geom.index_to_lps(0.5 * (v.geom.size[0] - 1.0), 0.5 * (v.geom.size[1] - 1.0), 0.5 * (v.geom.size[2] - 1.0));
  const ms::Vec3 u{v.geom.direction[0], v.geom.direction[3], v.geom.direction[6]};
  const double t = kDeg * M_PI / 180.0;
  using ms::operator+, ms::operator-, ms::operator*;
  auto back = [&](const ms::Vec3& q) {  // Rodrigues' rotation of q - c about u
    const ms::Vec3 d = q - c;
    return c + std::cos(t) * d + std::sin(t) * ms::cross(u, d) + (1 - std::cos(t)) * ms::dot(u, d) * u;
  };
  for (const char* l : {"Co_L", "Co_R", "Cr_L", "Cr_R", "Go_L", "Go_R", "Me", "Pog"}) {
    ASSERT_FALSE(a.at("landmarks").at(l).is_null()) << l;
    ASSERT_FALSE(b.at("landmarks").at(l).is_null()) << l;
    const double d = ms::distance(back(landmark(b, l)), landmark(a, l));
    std::printf("%s moved %.2f mm\n", l, d);
    EXPECT_LE(d, 3.0) << l;
  }
  fs::remove_all(dir);
}

// Menton and pogonion are midline points, and on a real symphysis whose
// lower border and labial profile are flat across the chin the lowest and
// most anterior points are ill-conditioned sideways (docs/landmarks.md,
// step 5). openkbp-train pt_92 (a tuning fold) resampled, turned 10 degrees
// and back: with the lowest point of the midline band, Me moved 9.8 mm
// (9.1 across the chin) and the menton deviation went from 6.7 to 2.4 mm;
// on the arch's midline, 0.5 mm and 0.4 / 0.1 mm.
TEST(EndToEnd, ResampledRealScanKeepsMentonOnTheChinsMidline) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "openkbp-train" / "pt_92" / "ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "shared data not present";
  const fs::path dir = temp_dir("pt92_resampled");
  const ms::Volume v = ms::io::read_scan(ct.string()).volume;
  const auto [a, b] = run_scan_and_copy(ct, turned_about(turned_about(v, 2, 10.0), 2, -10.0), dir);
  ASSERT_TRUE(a.is_object() && b.is_object());
  // Menton as a whole; pogonion across the chin (along the symmetry plane's
  // normal): up and down the chin it still follows the chin window's top
  // (B point found or not, docs/landmarks.md), which a resampling of a
  // ~4 mm scan can switch.
  const Value& n = a.at("symmetry_plane").at("normal");
  for (const char* l : {"Me", "Pog"}) {
    ASSERT_FALSE(a.at("landmarks").at(l).is_null()) << l;
    ASSERT_FALSE(b.at("landmarks").at(l).is_null()) << l;
    double d2 = 0, across = 0;
    for (std::size_t k = 0; k < 3; ++k) {
      const double d = b.at("landmarks").at(l)[k].get<double>() - a.at("landmarks").at(l)[k].get<double>();
      d2 += d * d;
      across += d * n[k].get<double>();
    }
    std::printf("%s moved %.2f mm, %.2f mm across the chin\n", l, std::sqrt(d2), std::abs(across));
    EXPECT_LE(std::string(l) == "Me" ? std::sqrt(d2) : std::abs(across), 3.0) << l;
  }
  const double ma = a.at("interpretation").at("menton_deviation").at("value").get<double>();
  const double mb = b.at("interpretation").at("menton_deviation").at("value").get<double>();
  std::printf("menton deviation %.2f / %.2f mm\n", ma, mb);
  EXPECT_NEAR(ma, mb, 1.5);
  fs::remove_all(dir);
}

// The same voxels stored with a 10 degree turn about the vertical written
// into the file's orientation: a storage change only. Gonion is where the
// bisector of the ramus and body tangents crosses the outline
// (docs/landmarks.md, step 4). As the surface point extreme along the
// bisector, it slid along this scan's rounded right angle: openkbp-train
// pt_101 (a tuning fold), Go_R moved 8.3 mm between the two files
// (scripts/validate-invariance, oblique).
TEST(EndToEnd, RealScanStoredTurnedKeepsItsGonia) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "openkbp-train" / "pt_101" / "ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "shared data not present";
  const fs::path dir = temp_dir("pt101_oblique");
  const ms::Volume v = ms::io::read_scan(ct.string()).volume;
  const double t = 10.0 * M_PI / 180.0, ct_ = std::cos(t), st = std::sin(t);
  const ms::Vec3 centre = v.geom.index_to_lps(0.5 * (v.geom.size[0] - 1.0), 0.5 * (v.geom.size[1] - 1.0), 0.5 * (v.geom.size[2] - 1.0));
  // The turn about the superior axis through the grid's centre, and back.
  auto turn = [&](const ms::Vec3& p, double sign) {
    const ms::Vec3 d{p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]};
    return ms::Vec3{centre[0] + ct_ * d[0] - sign * st * d[1], centre[1] + sign * st * d[0] + ct_ * d[1], p[2]};
  };
  ms::Volume w = v;
  for (int a = 0; a < 3; ++a) {  // the grid's axes (direction columns) turned
    const double x = v.geom.direction[a], y = v.geom.direction[3 + a];
    w.geom.direction[a] = ct_ * x - st * y;
    w.geom.direction[3 + a] = st * x + ct_ * y;
  }
  w.geom.origin = turn(v.geom.origin, 1.0);
  const auto [a, b] = run_scan_and_copy(ct, w, dir);
  ASSERT_TRUE(a.is_object() && b.is_object());
  for (const char* l : {"Go_L", "Go_R"}) {
    ASSERT_FALSE(a.at("landmarks").at(l).is_null()) << l;
    ASSERT_FALSE(b.at("landmarks").at(l).is_null()) << l;
    const double d = ms::distance(turn(landmark(b, l), -1.0), landmark(a, l));
    std::printf("%s moved %.2f mm\n", l, d);
    EXPECT_LE(d, 2.0) << l;
  }
  fs::remove_all(dir);
}

// Gonion follows a scan mirrored in its voxels (the head's left stored where
// its right was). The gonial tangents are chosen among hull edges, and on
// openkbp-train pt_172 (a tuning fold) the mirror's fraction of a degree of
// frame flipped the choice: an angle facet at 45 degrees changed class, and
// the posterior border, split into two hull edges, fell 0.1 mm short of the
// tangent length. Go_R moved 5.14 mm; now 0.01 mm.
TEST(EndToEnd, RealScanMirroredMirrorsItsGonia) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "openkbp-train" / "pt_172" / "ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "shared data not present";
  const fs::path dir = temp_dir("pt172_mirrored");
  const ms::Volume v = ms::io::read_scan(ct.string()).volume;
  ms::Volume w = v;  // the voxels mirrored along the grid's first axis, the geometry kept
  const auto& n = v.geom.size;
  for (std::size_t k = 0; k < n[2]; ++k)
    for (std::size_t j = 0; j < n[1]; ++j)
      for (std::size_t i = 0; i < n[0]; ++i) w.hu[v.geom.linear(i, j, k)] = v.hu[v.geom.linear(n[0] - 1 - i, j, k)];
  auto mirrored = [&](const ms::Vec3& p) {
    const ms::Vec3 q = v.geom.lps_to_index(p);
    return v.geom.index_to_lps(static_cast<double>(n[0] - 1) - q[0], q[1], q[2]);
  };
  const auto [a, b] = run_scan_and_copy(ct, w, dir);
  ASSERT_TRUE(a.is_object() && b.is_object());
  for (const auto& [l, m] : {std::pair<const char*, const char*>{"Go_L", "Go_R"}, {"Go_R", "Go_L"}}) {
    ASSERT_FALSE(a.at("landmarks").at(l).is_null()) << l;
    ASSERT_FALSE(b.at("landmarks").at(m).is_null()) << m;
    const double d = ms::distance(mirrored(landmark(b, m)), landmark(a, l));
    std::printf("%s: the mirror's %s %.2f mm from its mirror image\n", l, m, d);
    EXPECT_LE(d, 1.0) << l;
  }
  fs::remove_all(dir);
}

// Distance from p to the triangle (a, b, c): the projection when it falls
// inside, else the nearest of the three edges.
double point_triangle_distance(const ms::Vec3& p, const ms::Vec3& a, const ms::Vec3& b, const ms::Vec3& c) {
  auto sub = [](const ms::Vec3& x, const ms::Vec3& y) { return ms::Vec3{x[0] - y[0], x[1] - y[1], x[2] - y[2]}; };
  auto dot3 = [](const ms::Vec3& x, const ms::Vec3& y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; };
  auto cross3 = [](const ms::Vec3& x, const ms::Vec3& y) {
    return ms::Vec3{x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]};
  };
  auto segment = [&](const ms::Vec3& x, const ms::Vec3& y) {
    const ms::Vec3 d = sub(y, x);
    const double t = std::clamp(dot3(sub(p, x), d) / std::max(dot3(d, d), 1e-30), 0.0, 1.0);
    const ms::Vec3 q{x[0] + t * d[0], x[1] + t * d[1], x[2] + t * d[2]};
    return std::sqrt(dot3(sub(p, q), sub(p, q)));
  };
  const ms::Vec3 n = cross3(sub(b, a), sub(c, a));
  const double nn = dot3(n, n);
  if (nn > 1e-30) {
    const double h = dot3(sub(p, a), n) / nn;
    const ms::Vec3 q{p[0] - h * n[0], p[1] - h * n[1], p[2] - h * n[2]};
    if (dot3(cross3(sub(b, a), sub(q, a)), n) >= 0 && dot3(cross3(sub(c, b), sub(q, b)), n) >= 0 &&
        dot3(cross3(sub(a, c), sub(q, c)), n) >= 0)
      return std::abs(h) * std::sqrt(nn);
  }
  return std::min({segment(a, b), segment(b, c), segment(c, a)});
}

// Menton is a surface point. On openkbp-train pt_182 (a tuning fold, ~4 mm
// voxels) the lowest vertex of the symphysis's midline strip lies to one
// side, where the border is lower than on the midline: menton placed at that
// vertex's height floated 1.47 mm below the bone. It is where the vertical
// line at its midline position leaves the bone (docs/landmarks.md, step 5);
// the other landmarks are quadratic apex fits within about a millimetre.
TEST(EndToEnd, MentonLiesOnTheSurfaceOfACoarseRealScan) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "openkbp-train" / "pt_182" / "ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "shared data not present";
  const fs::path out = temp_dir("pt182");
  std::string err;
  ASSERT_EQ(run(openkbp_run_args(ct) + out.string(), &err), 0) << err;
  const Value r = load(out / "results.json");
  const ms::Mesh mesh = ms::surface::read_vtp((out / "mandible.vtp").string());
  ASSERT_GT(mesh.faces.size(), 1000u);
  for (const char* l : {"Co_L", "Co_R", "Cr_L", "Cr_R", "Go_L", "Go_R", "Me", "Pog"}) {
    const Value& v = r.at("landmarks").at(l);
    if (v.is_null()) continue;
    const ms::Vec3 p{v[0].get<double>(), v[1].get<double>(), v[2].get<double>()};
    double d = 1e30;
    for (const auto& f : mesh.faces)
      d = std::min(d, point_triangle_distance(p, mesh.vertices[static_cast<std::size_t>(f[0])], mesh.vertices[static_cast<std::size_t>(f[1])],
                                              mesh.vertices[static_cast<std::size_t>(f[2])]));
    std::printf("%s %.2f mm off the surface\n", l, d);
    EXPECT_LE(d, std::string(l) == "Me" ? 0.05 : 1.5) << l;
  }
  EXPECT_NE(r.at("qc").at("status").get<std::string>(), "fail");
  fs::remove_all(out);
}

// openkbp-train pt_47: one half of the mandible lacks its ramus and
// posterior body, in the clinical contour as in the mask (Dice 0.88). The
// landmarks of the missing half land on other structures; QC fails on the
// cause, the halves' atlas evidence (0.34; whole mandibles 0.81-1.00), and
// names it first (docs/qc.md, "halves_balance").
TEST(EndToEnd, AMandibleMissingPartOfAHalfFailsQcOnTheHalves) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "openkbp-train" / "pt_47" / "ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "shared data not present";
  const fs::path out = temp_dir("pt47");
  std::string err;
  ASSERT_EQ(run(openkbp_run_args(ct) + out.string(), &err), 8) << err;
  EXPECT_NE(err.find("one half of the mandible"), std::string::npos) << err;
  const Value r = load(out / "results.json");
  EXPECT_EQ(r.at("qc").at("status").get<std::string>(), "fail");
  EXPECT_LT(r.at("segmentation").at("atlas").at("halves_balance").get<double>(), 0.5);
  fs::remove_all(out);
}

// The slices [k0, k1) of a volume, in the same world space: a scan whose
// field of view covers less of the head.
ms::Volume slab_along_k(const ms::Volume& v, std::size_t k0, std::size_t k1) {
  ms::Volume out;
  out.geom = v.geom;
  out.geom.size[2] = k1 - k0;
  out.geom.origin = v.geom.index_to_lps(0, 0, static_cast<double>(k0));
  const std::size_t plane = v.geom.size[0] * v.geom.size[1];
  out.hu.assign(v.hu.begin() + static_cast<std::ptrdiff_t>(k0 * plane), v.hu.begin() + static_cast<std::ptrdiff_t>(k1 * plane));
  return out;
}

// A head CT whose field of view holds only part of the mandible, as a brain
// or a neck scan of a batch does: the Visible Human female (mandible at
// slices 22-103) from slice 75 up (the rami and the skull above them: the
// atlas fits at NCC 0.42 and the bone measured lies above the mandible) and
// below slice 62 (the body and the spine: the atlas cannot be placed). Each
// fails QC, and the failure says that the scan may not hold the mandible
// rather than what its symptoms would say alone ("one half resected").
TEST(EndToEnd, AScanThatDoesNotHoldTheMandibleFailsNamingTheFieldOfView) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "visible-human-female" / "ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "shared data not present";
  const fs::path dir = temp_dir("vhf_fov");
  fs::create_directories(dir);
  const ms::Volume v = ms::io::read_scan(ct.string()).volume;
  for (const auto& [name, k0, k1] : {std::tuple<const char*, std::size_t, std::size_t>{"above", 75, v.geom.size[2]}, {"below", 0, 62}}) {
    SCOPED_TRACE(name);
    ms::io::write_volume(slab_along_k(v, k0, k1), (dir / (std::string(name) + ".nii.gz")).string());
    const fs::path out = dir / name;
    std::string err;
    ASSERT_EQ(run("run " + (dir / (std::string(name) + ".nii.gz")).string() + " -q --no-cranial -o " + out.string(), &err), 8) << err;
    EXPECT_NE(err.find("may not hold the whole mandible"), std::string::npos) << err;
    EXPECT_EQ(err.find("resected"), std::string::npos) << err;
    const Value r = load(out / "results.json");
    EXPECT_EQ(r.at("qc").at("status").get<std::string>(), "fail");
    EXPECT_NE(r.at("qc").at("cause").get<std::string>().find("atlas"), std::string::npos);
    EXPECT_NE(slurp_file(out / "report.html").find("Likely cause: "), std::string::npos);
  }
  fs::remove_all(dir);
}

// Winding number of a closed mesh around p: the triangles' solid angles
// (Van Oosterom and Strackee 1983) over 4 pi; 1 inside an outward mesh, 0 outside.
double winding_number(const ms::Mesh& mesh, const ms::Vec3& p) {
  double sum = 0;
  for (const auto& f : mesh.faces) {
    ms::Vec3 r[3];
    double l[3];
    for (int k = 0; k < 3; ++k) {
      const ms::Vec3& v = mesh.vertices[static_cast<std::size_t>(f[static_cast<std::size_t>(k)])];
      r[k] = {v[0] - p[0], v[1] - p[1], v[2] - p[2]};
      l[k] = std::sqrt(r[k][0] * r[k][0] + r[k][1] * r[k][1] + r[k][2] * r[k][2]);
    }
    auto dot3 = [](const ms::Vec3& x, const ms::Vec3& y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; };
    const double triple = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) -
                          r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0]) +
                          r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
    const double den = l[0] * l[1] * l[2] + dot3(r[0], r[1]) * l[2] + dot3(r[1], r[2]) * l[0] + dot3(r[2], r[0]) * l[1];
    sum += 2 * std::atan2(triple, den);
  }
  return sum / (4 * M_PI);
}

// The surface holds the whole mask. At ~4.8 mm voxels a condylar neck one
// voxel thin is often continuous only across a voxel edge: on openkbp-train
// pt_172 (a tuning fold) the left condyle, 24 voxels, touched the ramus only
// diagonally, the iso-surface left it apart, the mesh kept its largest piece
// and Co_L was reported missing. The pieces are joined before contouring
// (docs/surface.md, step 1): every voxel centre of the mask lies inside the
// mesh, and all 8 landmarks are found.
TEST(EndToEnd, CondyleTouchingTheRamusDiagonallyStaysOnTheSurface) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "openkbp-train" / "pt_172" / "ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "shared data not present";
  const fs::path out = temp_dir("pt172");
  std::string err;
  ASSERT_EQ(run(openkbp_run_args(ct) + out.string(), &err), 0) << err;
  const Value r = load(out / "results.json");
  const ms::Mesh mesh = ms::surface::read_vtp((out / "mandible.vtp").string());
  const ms::Volume mask = ms::io::read_scan((out / "mandible_mask.nii.gz").string()).volume;
  std::size_t voxels = 0, outside = 0;
  for (std::size_t k = 0; k < mask.geom.size[2]; ++k)
    for (std::size_t j = 0; j < mask.geom.size[1]; ++j)
      for (std::size_t i = 0; i < mask.geom.size[0]; ++i) {
        if (mask.hu[i + mask.geom.size[0] * (j + mask.geom.size[1] * k)] < 0.5f) continue;
        ++voxels;
        outside += winding_number(mesh, mask.geom.index_to_lps(static_cast<double>(i), static_cast<double>(j),
                                                               static_cast<double>(k))) < 0.5;
      }
  std::printf("%zu of %zu mask voxel centres outside the mesh\n", outside, voxels);
  EXPECT_GT(voxels, 300u);
  EXPECT_EQ(outside, 0u);
  EXPECT_GT(r.at("mesh").at("voxels_joining_pieces").get<int>(), 0);
  for (const char* l : {"Co_L", "Co_R", "Cr_L", "Cr_R", "Go_L", "Go_R", "Me", "Pog"})
    EXPECT_FALSE(r.at("landmarks").at(l).is_null()) << l;
  // mandible_mask.nii.gz is on the input CT grid in the input's array order
  // (OUTPUTS.md): its voxels compare index by index with the clinical
  // contour, stored on the CT's grid. Ingest works in the canonical order
  // (core/array_order.h); written in that order (i and j reversed against
  // this RAS file), the index-wise Dice was 0.00.
  const std::string a = gunzip(out / "mandible_mask.nii.gz"), b = gunzip(ct.parent_path() / "mask.nii.gz");
  ASSERT_GT(a.size(), 352u);
  ASSERT_GT(b.size(), 352u);
  EXPECT_EQ(a.substr(40, 16), b.substr(40, 16));  // dim[0..7]
  const std::size_t oa = nifti_voxel_offset(a), ob = nifti_voxel_offset(b), n = a.size() - oa;
  ASSERT_EQ(n, b.size() - ob);
  std::size_t both = 0, na = 0, nb = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const bool x = a[oa + i] != 0, y = b[ob + i] != 0;
    both += x && y, na += x, nb += y;
  }
  const double index_dice = 2.0 * static_cast<double>(both) / static_cast<double>(na + nb);
  std::printf("index-wise Dice with the stored clinical contour %.3f\n", index_dice);
  EXPECT_GE(index_dice, 0.7);
  fs::remove_all(out);
}

// The volume reconstructed at twice its spacing: a Gaussian of sigma
// `sigma_voxels` along each axis (the wider slice profile of a coarser
// reconstruction), then the mean of each 2 x 2 x 2 block (ITK's
// DiscreteGaussianImageFilter and BinShrinkImageFilter), rounded to whole HU.
ms::Volume coarser_by_two(const ms::Volume& v, double sigma_voxels) {
  using Image = itk::Image<float, 3>;
  auto blur = itk::DiscreteGaussianImageFilter<Image, Image>::New();
  blur->SetInput(ms::io::float_view(v));
  blur->SetUseImageSpacing(false);
  blur->SetVariance(sigma_voxels * sigma_voxels);
  blur->SetMaximumKernelWidth(64);
  auto shrink = itk::BinShrinkImageFilter<Image, Image>::New();
  shrink->SetInput(blur->GetOutput());
  shrink->SetShrinkFactors(2);
  shrink->Update();
  const Image* img = shrink->GetOutput();
  ms::Volume out;
  out.geom = ms::io::geometry_of(img);
  const float* p = img->GetBufferPointer();
  out.hu.resize(out.geom.voxel_count());
  std::transform(p, p + out.hu.size(), out.hu.begin(), [](float x) { return std::round(x); });
  return out;
}

// The volume reconstructed at an isotropic `spacing` (mm): a Gaussian of
// sigma 0.42 x spacing (the slice profile of a coarser reconstruction), then
// trilinear at the new voxel centres from the same origin (ITK's
// DiscreteGaussianImageFilter and ResampleImageFilter), rounded to whole HU.
ms::Volume reconstructed_at(const ms::Volume& v, double spacing) {
  using Image = itk::Image<float, 3>;
  auto blur = itk::DiscreteGaussianImageFilter<Image, Image>::New();
  blur->SetInput(ms::io::float_view(v));
  blur->SetUseImageSpacing(true);
  blur->SetVariance(std::pow(0.42 * spacing, 2));
  blur->SetMaximumKernelWidth(64);
  auto resample = itk::ResampleImageFilter<Image, Image>::New();
  resample->SetInput(blur->GetOutput());
  Image::SizeType size;
  Image::SpacingType sp;
  for (int a = 0; a < 3; ++a)
    size[a] = static_cast<std::size_t>(std::floor((v.geom.size[a] - 1) * v.geom.spacing[a] / spacing)) + 1, sp[a] = spacing;
  resample->SetSize(size);
  resample->SetOutputSpacing(sp);
  resample->SetOutputOrigin(ms::io::float_view(v)->GetOrigin());
  resample->SetOutputDirection(ms::io::float_view(v)->GetDirection());
  resample->Update();
  ms::Volume out;
  out.geom = ms::io::geometry_of(resample->GetOutput());
  const float* p = resample->GetOutput()->GetBufferPointer();
  out.hu.resize(out.geom.voxel_count());
  std::transform(p, p + out.hu.size(), out.hu.begin(), [](float x) { return std::round(x); });
  return out;
}

// Runs the Visible Human female head as `v` (a reconstruction of it) and
// expects QC pass and every landmark within tol_mm of its reference
// (tests/data/visible-human-female, docs/reference-vhf.md). Returns results.json.
Value expect_vhf_landmarks_within(const ms::Volume& v, const std::string& name, double tol_mm) {
  const fs::path dir = temp_dir(name);
  fs::create_directories(dir);
  ms::io::write_volume(v, (dir / (name + ".nii.gz")).string());
  std::string err;
  if (run("run " + (dir / (name + ".nii.gz")).string() + " -o " + (dir / "out").string() + " -q --no-figures --no-cranial", &err) != 0) {
    ADD_FAILURE() << err;
    return Value();
  }
  const Value r = load(dir / "out" / "results.json");
  const Value ref = load(fs::path(MANDISYM_SOURCE_DIR) / "tests" / "data" / "visible-human-female" / "reference_landmarks.json").at("landmarks");
  EXPECT_EQ(r.at("qc").at("status").get<std::string>(), "pass");
  std::printf("volume %.1f cm3, %s\n", r.at("segmentation").at("volume_mm3").get<double>() / 1000,
              r.at("segmentation").at("marker_source").get<std::string>().c_str());
  for (const char* l : {"Co_L", "Co_R", "Cr_L", "Cr_R", "Go_L", "Go_R", "Me", "Pog"}) {
    const Value& p = r.at("landmarks").at(l);
    if (p.is_null()) {
      ADD_FAILURE() << l << " missing";
      continue;
    }
    double d2 = 0;
    for (std::size_t a = 0; a < 3; ++a) d2 += std::pow(p[a].get<double>() - ref.at(l)[a].get<double>(), 2);
    std::printf("%s %.1f mm from the reference\n", l, std::sqrt(d2));
    EXPECT_LE(std::sqrt(d2), tol_mm) << l;
  }
  fs::remove_all(dir);
  return r;
}

// The Visible Human head reconstructed at 1.5 mm. The zone, not cut at the
// joints there before (docs/segmentation.md, step 4: kJointResolvingSpacingMm
// was 1.25 mm), took the fossa roofs: condylion 2.7 / 4.4 mm from the
// reference. A 1.5 mm voxel still shows the 2.5 mm superior joint space as
// a valley under the bone threshold; cut there: 0.3 / 1.3 mm.
TEST(EndToEnd, RealHeadAtOneAndAHalfMillimetresIsCutAtItsJoints) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "visible-human-female" / "ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "shared data not present";
  expect_vhf_landmarks_within(reconstructed_at(ms::io::read_scan(ct.string()).volume, 1.5), "vhf_1p5mm", 3.0);  // two voxels
}

// The Visible Human head reconstructed at 2 mm. The image separation took
// it (scans up to 2 mm) and cut off both rami, inside the atlas's support:
// 37 cm3, landmarks 60-88 mm off, and QC only warned. Voxels of 2 mm do not
// resolve the joint spaces the image separation is for; the atlas's zone is
// the answer there (docs/segmentation.md, step 6): QC passes and the
// landmarks are within a few voxels of the reference.
TEST(EndToEnd, RealHeadAtTwoMillimetresKeepsItsRami) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "visible-human-female" / "ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "shared data not present";
  expect_vhf_landmarks_within(coarser_by_two(ms::io::read_scan(ct.string()).volume, 0.84), "vhf_2mm", 8.0);
}

// Runs openkbp-train patient pid automatically and on its clinical contour
// (--mask); on each side, condylion must lie at least 20 mm behind the
// coronoid tip (the minimum ramus breadth is ~25-33 mm in adults; Humphrey
// et al. 1999) and the coronoid tip within 5 mm of the contour run's.
// Returns the automatic run's results (null when it did not run).
Value expect_two_processes_per_side(const std::string& pid) {
  const fs::path dir = fs::path(MANDISYM_SHARED_DATA) / "openkbp-train" / pid;
  const fs::path out = temp_dir(pid + "_out"), contour = temp_dir(pid + "_contour");
  std::string err;
  const std::string common = openkbp_run_args(dir / "ct.nii.gz");
  if (run(common + out.string(), &err) != 0 || run(common + contour.string() + " --mask " + (dir / "mask.nii.gz").string(), &err) != 0) {
    ADD_FAILURE() << pid << ": " << err;
    return Value();
  }
  const Value r = load(out / "results.json"), c = load(contour / "results.json");
  for (const char* side : {"_L", "_R"}) {
    const std::string co = std::string("Co") + side, cr = std::string("Cr") + side;
    if (r.at("landmarks").at(co).is_null() || r.at("landmarks").at(cr).is_null() || c.at("landmarks").at(cr).is_null()) {
      ADD_FAILURE() << pid << ": " << co << " or " << cr << " missing";
      continue;
    }
    const ms::Vec3 pcr = landmark(r, cr);
    const double behind = landmark(r, co)[1] - pcr[1];  // LPS y: posterior (these heads are upright)
    const double d = ms::distance(pcr, landmark(c, cr));
    std::printf("%s: %s %.1f mm behind %s; %s %.1f mm from the contour's\n", pid.c_str(), co.c_str(), behind, cr.c_str(), cr.c_str(), d);
    EXPECT_GE(behind, 20.0) << pid << " " << co;
    EXPECT_LE(d, 5.0) << pid << " " << cr;
  }
  fs::remove_all(out);
  fs::remove_all(contour);
  return r;
}

// A real scan whose condylar necks are one voxel thin at 4.7 x 4.7 x 3 mm
// and touch the ramus only across voxel edges (openkbp-train pt_20, a
// tuning-fold patient). The mesh used to leave both condyles out; the
// ramus's one process was the coronoid, and step 3's check reported Co
// missing rather than the coronoid as Co (docs/landmarks.md). With the
// pieces joined (docs/surface.md, step 1) both condylia are found, behind
// their coronoids by about a ramus's breadth (29-33 mm in adults; at least
// 20 mm here), and Cr is where the same detector on the clinical contour
// (--mask) puts it.
TEST(EndToEnd, RealScanWithDiagonallyJoinedCondylesFindsThem) {
  if (!fs::exists(fs::path(MANDISYM_SHARED_DATA) / "openkbp-train" / "pt_20" / "ct.nii.gz")) GTEST_SKIP() << "shared data not present";
  const Value r = expect_two_processes_per_side("pt_20");
  ASSERT_TRUE(r.is_object());
  EXPECT_GT(r.at("mesh").at("voxels_joining_pieces").get<int>(), 0);
}

// The coronoid tip is the apex of a process distinct from the condyle's:
// on openkbp-train pt_30 (a tuning fold) the right ramus's second-highest
// extremity lies on the front of the condylar neck and its apex climbed to
// the condylar head, so the "coronoid tip" was 9.0 mm from condylion (QC
// warn, process_pair_mismatch_mm). The pair is now checked at its apexes
// (docs/landmarks.md, step 3): Cr_R is the coronoid's, 2.8 mm from the
// contour run's.
TEST(EndToEnd, CoronoidTipIsNotOnTheCondylarHead) {
  if (!fs::exists(fs::path(MANDISYM_SHARED_DATA) / "openkbp-train" / "pt_30" / "ct.nii.gz")) GTEST_SKIP() << "shared data not present";
  const Value r = expect_two_processes_per_side("pt_30");
  ASSERT_TRUE(r.is_object());
  EXPECT_EQ(r.at("qc").at("status").get<std::string>(), "pass");
}

// Coronoid tips taller than every training mandible's (docs/segmentation.md,
// step 3, "Processes past the support"): on openkbp-train pt_122 (a tuning
// fold, 3.9 mm voxels) both tips are pieces the bone threshold cut from
// their processes, reaching a few millimetres beyond the atlas's support,
// and were left out: Cr_L lay 9.1 mm and Cr_R 17.0 mm from the contour run's.
// Within the support grown by 5 mm and above the atlas's sigmoid notch they
// join: 2.8 and 0.0 mm.
TEST(EndToEnd, CoronoidTipsTallerThanTheAtlasJoinTheirProcesses) {
  if (!fs::exists(fs::path(MANDISYM_SHARED_DATA) / "openkbp-train" / "pt_122" / "ct.nii.gz")) GTEST_SKIP() << "shared data not present";
  const Value r = expect_two_processes_per_side("pt_122");
  ASSERT_TRUE(r.is_object());
  EXPECT_EQ(r.at("qc").at("status").get<std::string>(), "pass");
}

// A condyle deeper than the posterior-border check allows, over the front of
// its section, stays the condyle when it stands nearer the placed atlas's
// condyle than its coronoid (docs/landmarks.md, step 3). On openkbp-train
// pt_99 (fold 5: the held-out fold, which this rule was seen on; no
// threshold was set on it) the left condyle lies 15.4 mm in front of the
// border over 0.38 of its section: it was reported as the coronoid, Co_L
// missing (no SAF score, QC warn), in the automatic and the contour run.
TEST(EndToEnd, ADeepCondyleNearTheAtlasCondyleIsTheCondyle) {
  const fs::path ct = fs::path(MANDISYM_SHARED_DATA) / "openkbp-train" / "pt_99" / "ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "shared data not present";
  const fs::path out = temp_dir("pt_99_out");
  std::string err;
  ASSERT_EQ(run(openkbp_run_args(ct) + out.string(), &err), 0) << err;
  const Value r = load(out / "results.json");
  for (const char* l : {"Co_L", "Co_R", "Cr_L", "Cr_R"}) ASSERT_FALSE(r.at("landmarks").at(l).is_null()) << l;
  // LPS y is posterior (this head is upright): each condyle ~36 mm behind its
  // coronoid tip, the two condyles level front to back (within 5 mm).
  const double behind_l = landmark(r, "Co_L")[1] - landmark(r, "Cr_L")[1], behind_r = landmark(r, "Co_R")[1] - landmark(r, "Cr_R")[1];
  std::printf("pt_99: Co_L %.1f mm behind Cr_L, Co_R %.1f mm behind Cr_R\n", behind_l, behind_r);
  EXPECT_GE(behind_l, 20.0);
  EXPECT_GE(behind_r, 20.0);
  EXPECT_NEAR(landmark(r, "Co_L")[1], landmark(r, "Co_R")[1], 5.0);
  EXPECT_EQ(r.at("qc").at("status").get<std::string>(), "pass");
  EXPECT_TRUE(r.at("scores").at("saf").at("score").is_number());
  fs::remove_all(out);
}

// An external mask is labelled in the head frame of the automatic run of the
// same scan (docs/landmarks.md, "Head frame order"): the atlas is placed in
// the CT for it too. On openkbp-train pt_183 (a tuning fold) the clinical
// contour's run (--mask) took a nasal floor found 50 degrees from the
// atlas's superior: its gonia lay 22-25 mm and its menton 17 mm from the
// automatic run's, and QC failed (menton above the condyles). In the atlas's
// frame, as the automatic run: 2.0 / 2.3 and 0.2 mm.
TEST(EndToEnd, ExternalMaskIsLabelledInTheAtlasHeadFrame) {
  const fs::path dir = fs::path(MANDISYM_SHARED_DATA) / "openkbp-train" / "pt_183";
  if (!fs::exists(dir / "ct.nii.gz")) GTEST_SKIP() << "shared data not present";
  const fs::path out = temp_dir("pt_183_auto"), contour = temp_dir("pt_183_mask");
  std::string err;
  const std::string common = openkbp_run_args(dir / "ct.nii.gz");
  ASSERT_EQ(run(common + out.string(), &err), 0) << err;
  ASSERT_EQ(run(common + contour.string() + " --mask " + (dir / "mask.nii.gz").string(), &err), 0) << err;
  const Value r = load(out / "results.json"), c = load(contour / "results.json");
  EXPECT_EQ(c.at("head_frame").at("source").get<std::string>(), "mandible atlas");
  EXPECT_EQ(c.at("head_frame").at("source"), r.at("head_frame").at("source"));
  const Value& atlas = c.at("segmentation").at("atlas");
  EXPECT_TRUE(atlas.at("found").get<bool>());
  EXPECT_TRUE(atlas.at("agreement").is_null());  // placed for the frame, not to judge the mask
  EXPECT_NE(c.at("qc").at("status").get<std::string>(), "fail");
  for (const char* l : {"Go_L", "Go_R", "Me"}) {
    ASSERT_FALSE(r.at("landmarks").at(l).is_null() || c.at("landmarks").at(l).is_null()) << l;
    const double d = ms::distance(landmark(r, l), landmark(c, l));
    std::printf("%s %.1f mm from the automatic run's\n", l, d);
    EXPECT_LE(d, 5.0) << l;
  }
  fs::remove_all(out);
  fs::remove_all(contour);
}

// With its own segmentation of a scan that resolves the cortex, the surface
// is placed between voxels where the CT crosses the segmentation's surface
// level (docs/surface.md, "Sub-voxel placement"): the mesh keeps the mask's
// volume. An external mask is contoured as it is.
TEST(EndToEnd, SurfaceFollowsTheCtOnlyWithItsOwnSegmentation) {
  const Value& r = results("symmetric");
  ASSERT_TRUE(r.is_object());
  const double level = r.at("parameters").at("surface_guide_level_hu").get<double>();
  const double offset = r.at("segmentation").at("calibration_offset_hu").get<double>();
  EXPECT_NEAR(level, 700.0 + offset, 1e-3);
  const double mesh = r.at("mesh").at("volume_mm3").get<double>(), mask = r.at("segmentation").at("volume_mm3").get<double>();
  EXPECT_NEAR(mesh, mask, 0.02 * mask);
  const fs::path out = temp_dir("external_mask");
  std::string err;
  ASSERT_EQ(run("run " + (kSamples / "symmetric" / "dicom").string() + " --mask " +
                    (kSamples / "symmetric" / "ground_truth" / "mandible_mask.nii.gz").string() + " --no-figures -q -o " +
                    out.string(),
                &err),
            0)
      << err;
  const Value e = load(out / "results.json");
  EXPECT_EQ(e.at("parameters").at("surface_guide_level_hu").get<std::string>(), "none");
  fs::remove_all(out);
}

// A symmetric head at an oblique pose is not mistaken for asymmetry: through
// the whole chain (own segmentation, surface with its automatic handle
// closing, detected landmarks) it scores below a head with the left ramus
// 2 mm longer at the neutral pose. Measured 0.0043 vs 0.0101 rad (0.0050 vs
// 0.0125 before the SAF's disks were cut into the mesh); when the whole 2 mm
// closing was kept (it fills creases differently left and right on the voxel
// grid at that pose) 0.0193 vs 0.0127 (docs/method.md).
TEST(EndToEnd, ObliquePoseScoresBelowATwoMillimetreRamusDifference) {
  auto score = [](const std::string& name, const std::string& knobs, std::string& scope) {
    const fs::path ph = temp_dir(name + "_phantom"), out = temp_dir(name + "_out");
    EXPECT_EQ(run("phantom -o " + ph.string() + " --spacing 1 " + knobs + " --no-preview"), 0) << name;
    std::string err;
    EXPECT_EQ(run("run " + (ph / "dicom").string() + " -o " + out.string() + " -q --no-figures --no-cranial", &err), 0) << err;
    const Value r = load(out / "results.json");
    scope = r.at("mesh").at("closing_scope").get<std::string>();
    const double saf = r.at("scores").at("saf").at("score").get<double>();
    std::printf("%s: SAF %.4f rad, closing %s\n", name.c_str(), saf, scope.c_str());
    fs::remove_all(ph);
    fs::remove_all(out);
    return saf;
  };
  std::string scope_sym, scope_ramus;
  const double sym = score("oblique_symmetric", "--yaw -12 --roll 10", scope_sym);
  const double ramus = score("neutral_ramus2", "--ramus-L 2", scope_ramus);
  // Teeth in contact may make handles; then only their plugs are kept, never
  // the whole closing. (Whether the voxel-diagonal contacts are handles at all
  // is decided by marching cubes' ambiguous faces: since the surface is built
  // in a canonical orientation, this pose meshes without any, 0.0043 rad.)
  EXPECT_NE(scope_sym, "everywhere");
  EXPECT_LT(sym, 0.6 * ramus);
}

// The random anatomy family (docs/phantom.md, "Random anatomy"): eight
// members drawn from adult ranges (size, ramus, body, gonial angle, condyles,
// cortex, densities, joint space, occlusal gap, crowns). A rule tuned to the
// one adult model fails here: each member is either right (volume within 5 %
// of the truth, every landmark within 3 mm) or refused by the quality gate
// (exit 8) — never a confident wrong answer, and never a right one refused —
// and most are right. Measured at
// 1 mm: 7 right (volumes within 5 %, landmarks <= 1.5 mm), member 8 exits 8
// (separations_agree 0.72: its rami reach beyond the atlas's support grown by
// 5 mm, docs/segmentation.md), and its refusal does not blame the teeth (1.5 mm
// apart; 3 mm2 of its cheek-teeth columns rise 12 mm above the zone, 100 needed).
TEST(EndToEnd, RandomAnatomyFamilyIsRightOrRefused) {
  int right = 0;
  for (int n = 1; n <= 8; ++n) {
    const std::string name = "random_anatomy_" + std::to_string(n);
    const fs::path ph = temp_dir(name + "_phantom"), out = temp_dir(name + "_out");
    ASSERT_EQ(run("phantom -o " + ph.string() + " --spacing 1 --random-anatomy " + std::to_string(n) + " --no-preview"), 0) << name;
    std::string err;
    const int code = run("run " + (ph / "dicom").string() + " -o " + out.string() + " -q --no-figures --no-cranial", &err);
    ASSERT_TRUE(code == 0 || code == 8) << name << ": exit " << code << ": " << err;
    const Value r = load(out / "results.json");
    const Value truth = load(ph / "ground_truth" / "landmarks.json").at("landmarks");
    const double volume = r.at("segmentation").at("volume_mm3").get<double>();
    const double true_volume = load(ph / "ground_truth" / "params.json").at("mandible_volume_mm3").get<double>();
    double worst = 0;
    for (const char* l : {"Co_L", "Co_R", "Cr_L", "Cr_R", "Go_L", "Go_R", "Me", "Pog"}) {
      const Value& p = r.at("landmarks").at(l);
      if (p.is_null()) {
        worst = 1e9;
        continue;
      }
      double d2 = 0;
      for (std::size_t a = 0; a < 3; ++a) d2 += std::pow(p[a].get<double>() - truth.at(l)[a].get<double>(), 2);
      worst = std::max(worst, std::sqrt(d2));
    }
    const bool is_right = std::abs(volume / true_volume - 1) <= 0.05 && worst <= 3.0;
    std::printf("%s: exit %d, volume %.1f of %.1f cm3, worst landmark %.1f mm, qc %s\n", name.c_str(), code, volume / 1000,
                true_volume / 1000, worst, r.at("qc").at("status").get<std::string>().c_str());
    EXPECT_TRUE(is_right || code == 8) << name << ": a wrong answer that passed the quality gate";
    EXPECT_FALSE(is_right && code == 8) << name << ": a right answer refused by the quality gate";
    // A refusal names its cause: teeth in occlusion only when the teeth touch
    // (member 8, teeth 1.5 mm apart, is refused for its long rami).
    const double gap = load(ph / "ground_truth" / "params.json").at("occlusal_gap_mm").get<double>();
    for (const Value& c : r.at("qc").at("checks"))
      if (c.at("name").get<std::string>() == "separations_agree" && gap >= 1.0)
        EXPECT_EQ(c.value("meaning", std::string()).find("teeth in occlusion"), std::string::npos)
            << name << ": teeth " << gap << " mm apart read as welded";
    right += is_right;
    fs::remove_all(ph);
    fs::remove_all(out);
  }
  EXPECT_GE(right, 7);
}

// A head pitched 20 degrees chin-up in the scanner: the run finds the palatal
// plane, reports the tilt, and places menton and pogonion in the head's frame
// (with the scan's superior they were 10 and 4 mm off, docs/landmarks.md).
TEST(EndToEnd, PitchedHeadIsCorrectedByThePalatalPlane) {
  const fs::path ph = temp_dir("pitched_phantom"), out = temp_dir("pitched_out");
  ASSERT_EQ(run("phantom -o " + ph.string() + " --spacing 1 --fov 150,140,130 --pitch -20 --occlusal-gap 2 --no-preview"), 0);
  std::string err;
  ASSERT_EQ(run("run " + (ph / "dicom").string() + " -o " + out.string() + " -q --no-cranial", &err), 0) << err;
  const Value r = load(out / "results.json");
  const Value& hf = r.at("head_frame");
  ASSERT_EQ(hf.at("source").get<std::string>(), "palatal plane");
  // The floor's candidates: with air above on the image-separated mask (84 cm3), under soft
  // tissue with the atlas-zone mask (71 cm3, whose incisal edges bound the search lower); the
  // line is the same within 1 degree (tilt 13.0 / 13.8).
  EXPECT_TRUE(hf.at("palatal_floor").get<std::string>() == "air" || hf.at("palatal_floor").get<std::string>() == "soft tissue");
  EXPECT_NEAR(hf.at("palatal_tilt_deg").get<double>(), -20.0, 1.0);
  const Value truth = load(ph / "ground_truth" / "landmarks.json");
  for (const char* name : {"Me", "Pog", "Cr_L", "Cr_R"}) {
    double d2 = 0;
    for (std::size_t a = 0; a < 3; ++a) {
      const double d = r.at("landmarks").at(name)[a].get<double>() - truth.at("landmarks").at(name)[a].get<double>();
      d2 += d * d;
    }
    EXPECT_LT(std::sqrt(d2), 2.0) << name;
  }
  EXPECT_TRUE(fs::exists(out / "qc" / "qc_head_frame.png"));
  fs::remove_all(ph);
  fs::remove_all(out);
}

// headsq (real, 3.2 mm voxels) with its orientation given: the nasal floor
// is found on air; the head lies flexed in the scanner (measured 12.9 deg),
// and the corrected frame finds both gonia.
TEST(EndToEnd, HeadsqPalatalPlaneIsFoundOnTheNasalFloor) {
  const fs::path nhdr = headsq_nhdr();
  if (nhdr.empty()) GTEST_SKIP() << "shared data not present";
  const fs::path out = temp_dir("headsq_lpi");
  std::string err;
  ASSERT_EQ(run("run " + nhdr.string() + " --hu-offset -1024 --orientation LPI -o " + out.string() + " -q --no-figures", &err), 0) << err;
  const Value r = load(out / "results.json");
  const Value& hf = r.at("head_frame");
  ASSERT_EQ(hf.at("source").get<std::string>(), "palatal plane");
  // The floor's candidates: with air above on the image-separated mask (84 cm3), under soft
  // tissue with the atlas-zone mask (71 cm3, whose incisal edges bound the search lower); the
  // line is the same within 1 degree (tilt 13.0 / 13.8).
  EXPECT_TRUE(hf.at("palatal_floor").get<std::string>() == "air" || hf.at("palatal_floor").get<std::string>() == "soft tissue");
  EXPECT_GT(hf.at("palatal_tilt_deg").get<double>(), 5.0);
  EXPECT_LT(hf.at("palatal_tilt_deg").get<double>(), 20.0);
  EXPECT_LT(hf.at("palatal_rms_mm").get<double>(), 1.0);
  EXPECT_TRUE(r.at("landmarks").at("Go_L").is_array());
  EXPECT_TRUE(r.at("landmarks").at("Go_R").is_array());
  fs::remove_all(out);
}

TEST(EndToEnd, PatientIdentityNeverReachesTheOutputs) {
  // A phantom series written with a recognisable name and ID.
  const fs::path ph = temp_dir("privacy_ph"), out = temp_dir("privacy_out");
  ASSERT_EQ(run("phantom -o " + ph.string() + " --spacing 1 --fov 140,120,120 --occlusal-gap 3 --joint-space 3 --no-preview"), 0);
  // Re-stamp the identity into every slice header (same length, so offsets stay valid).
  for (const auto& e : fs::directory_iterator(ph / "dicom")) {
    std::fstream f(e.path(), std::ios::in | std::ios::out | std::ios::binary);
    std::stringstream s;
    s << f.rdbuf();
    std::string bytes = s.str();
    for (const auto& [from, to] : {std::pair<std::string, std::string>{"ANONYMOUS^PHANTOM", "ZZSECRET^PERSON__"},
                                   std::pair<std::string, std::string>{"PHANTOM", "ZZSECID"}}) {
      for (std::size_t p = bytes.find(from); p != std::string::npos; p = bytes.find(from, p + 1)) bytes.replace(p, to.size(), to);
    }
    f.seekp(0);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  std::string err;
  ASSERT_EQ(run("run " + (ph / "dicom").string() + " -o " + out.string(), &err), 0) << err;
  for (const auto& e : fs::recursive_directory_iterator(out)) {
    if (!e.is_regular_file()) continue;
    std::ifstream f(e.path(), std::ios::binary);
    std::stringstream s;
    s << f.rdbuf();
    EXPECT_EQ(s.str().find("ZZSECRET"), std::string::npos) << e.path();
    EXPECT_EQ(s.str().find("ZZSECID"), std::string::npos) << e.path();
  }
  fs::remove_all(ph);
  fs::remove_all(out);
}

// Replaces every occurrence of `from` by `to` (same length) in the files of dir.
void patch_files(const fs::path& dir, const std::string& from, const std::string& to) {
  ASSERT_EQ(from.size(), to.size());
  for (const auto& e : fs::directory_iterator(dir)) {
    std::fstream f(e.path(), std::ios::in | std::ios::out | std::ios::binary);
    std::stringstream s;
    s << f.rdbuf();
    std::string bytes = s.str();
    for (std::size_t p = bytes.find(from); p != std::string::npos; p = bytes.find(from, p + 1)) bytes.replace(p, to.size(), to);
    f.seekp(0);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
}

TEST(EndToEnd, DicomStringsAreEscapedAndDeidentifyRemovesThem) {
  const fs::path ph = temp_dir("escape_ph"), out = temp_dir("escape_out"), anon = temp_dir("escape_anon");
  ASSERT_EQ(run("phantom -o " + ph.string() + " --spacing 1 --fov 140,120,120 --occlusal-gap 3 --joint-space 3 --no-preview"), 0);
  // Series description and manufacturer carrying markup (same byte lengths).
  patch_files(ph / "dicom", "MandiSym synthetic head CT", "<script>alert(1)</script> ");
  patch_files(ph / "dicom", "MandiSym", "A&\"B'<i>");
  std::string err;
  ASSERT_EQ(run("run " + (ph / "dicom").string() + " -o " + out.string() + " --no-figures -q", &err), 0) << err;
  const std::string html = slurp_file(out / "report.html");
  EXPECT_EQ(html.find("<script>alert(1)"), std::string::npos);
  EXPECT_NE(html.find("&lt;script&gt;alert(1)&lt;/script&gt;"), std::string::npos);
  EXPECT_EQ(html.find("A&\"B'<i>"), std::string::npos);
  EXPECT_NE(html.find("A&amp;&quot;B&#39;&lt;i&gt;"), std::string::npos) << "manufacturer not shown escaped";
  // results.json stays valid JSON with the raw strings inside.
  const Value r = load(out / "results.json");
  EXPECT_EQ(r.at("input").at("manufacturer").get<std::string>(), "A&\"B'<i>");

  // --deidentify: UIDs, dates, descriptions and the input path reach no output.
  const std::string uid = r.at("input").at("series_uid").get<std::string>();
  ASSERT_FALSE(uid.empty());
  ASSERT_EQ(run("run " + (ph / "dicom").string() + " -o " + anon.string() + " --no-figures --deidentify -q", &err), 0) << err;
  for (const auto& e : fs::recursive_directory_iterator(anon)) {
    if (!e.is_regular_file()) continue;
    const std::string s = slurp_file(e.path());
    for (const std::string& secret : {uid, std::string("20260101"), std::string("alert(1)"), ph.string()})
      EXPECT_EQ(s.find(secret), std::string::npos) << e.path() << " contains " << secret;
  }
  // report.pdf's text is compressed: read it with poppler where installed.
  if (std::system("command -v pdftotext > /dev/null 2>&1") == 0) {
    ASSERT_EQ(std::system(("pdftotext " + (anon / "report.pdf").string() + " " + (anon / "pdf.txt").string()).c_str()), 0);
    const std::string text = slurp_file(anon / "pdf.txt");
    EXPECT_NE(text.find("asymmetry"), std::string::npos) << "pdftotext read nothing";
    for (const std::string& secret : {uid, std::string("2026-01-01"), std::string("20260101"), std::string("alert(1)"), ph.string()})
      EXPECT_EQ(text.find(secret), std::string::npos) << "report.pdf contains " << secret;
  }
  fs::remove_all(ph);
  fs::remove_all(out);
  fs::remove_all(anon);
}

namespace {

TEST(EndToEnd, CompareMeasuresTheChangeBetweenTwoScans) {
  const fs::path src = fs::path(MANDISYM_SOURCE_DIR) / "sample_dicom";
  const fs::path pre = temp_dir("cmp_pre"), out = temp_dir("cmp_out"), same = temp_dir("cmp_same");
  std::string err;
  ASSERT_EQ(run("run " + (src / "symmetric" / "dicom").string() + " -o " + pre.string() + " -q --no-figures", &err), 0) << err;
  // POST given as a scan: compare runs it itself into out/post.
  ASSERT_EQ(run("compare " + pre.string() + " " + (src / "ramus_L_plus4mm" / "dicom").string() + " -o " + out.string() + " -q", &err), 0)
      << err;
  const Value c = load(out / "compare.json");
  EXPECT_TRUE(fs::exists(out / "post" / "results.json"));
  EXPECT_TRUE(fs::exists(out / "post_aligned.vtp"));
  EXPECT_TRUE(fs::exists(out / "compare.html"));
  EXPECT_EQ(c.at("alignment").at("landmark_pairs").get<double>(), 8);
  EXPECT_LT(c.at("alignment").at("rotation_deg").get<double>(), 1.0);
  // The left condyle rose by 4 mm between the two scans.
  const double out_mm = c.at("change").at("max_outward_mm").get<double>();
  EXPECT_GT(out_mm, 3.0);
  EXPECT_LT(out_mm, 4.5);
  EXPECT_LT(c.at("change").at("mean_abs_mm").get<double>(), 0.3);  // elsewhere unchanged
  const double ramus = c.at("scores").at("ramus_height_mm_diff").at("change").get<double>();
  EXPECT_GT(ramus, 2.5);
  EXPECT_LT(ramus, 4.5);
  // SRD: the left condyle's neighbourhood changed more than the chin's.
  const Value& srd = c.at("srd");
  ASSERT_TRUE(srd.contains("Co_L") && srd.contains("Pog"));
  EXPECT_GT(srd.at("Co_L").at("pre_post_distance_rad").get<double>(), srd.at("Pog").at("pre_post_distance_rad").get<double>());
  // Every landmark's neighbourhood registers and agrees with post's own
  // detection: nothing is transferred on these clean scans.
  const Value& tr = c.at("landmark_transfer");
  EXPECT_EQ(tr.size(), 8u);
  for (const auto& [name, t] : tr.items()) {
    EXPECT_TRUE(t.at("registered").get<bool>()) << name;
    EXPECT_FALSE(t.at("used").get<bool>()) << name << ": " << t.at("reason").get<std::string>();
    EXPECT_LT(t.at("disagreement_mm").get<double>(), 3.0) << name;
  }
  EXPECT_EQ(c.at("landmarks_transferred").size(), 0u);
  // The same scan twice: no change.
  ASSERT_EQ(run("compare " + pre.string() + " " + pre.string() + " -o " + same.string() + " -q", &err), 0) << err;
  const Value s = load(same / "compare.json");
  EXPECT_LT(s.at("change").at("p95_mm").get<double>(), 0.05);
  EXPECT_NEAR(s.at("scores").at("saf_score").at("change").get<double>(), 0.0, 1e-12);
  EXPECT_NEAR(s.at("srd").at("Co_L").at("pre_post_distance_rad").get<double>(), 0.0, 1e-5);  // srd.json rounds to 1e-6
  // A post run whose detector misplaced Go_L by 7 mm and missed Me (as a
  // plate or an osteotomy gap can make it): both come back from pre, and
  // post's bilateral measurements are taken again with them.
  const fs::path bad = temp_dir("cmp_bad"), fixed = temp_dir("cmp_fixed");
  fs::create_directories(bad);
  for (const char* f : {"results.json", "mandible.vtp", "srd.json"}) fs::copy_file(pre / f, bad / f);
  {
    Value r = load(pre / "results.json");
    Value& lm = r["landmarks"];
    const double z = lm.at("Go_L")[2].get<double>();
    lm["Go_L"][2] = Value(z - 7);
    lm["Me"] = Value();
    std::ofstream(bad / "results.json") << r.dump(2);
  }
  ASSERT_EQ(run("compare " + pre.string() + " " + bad.string() + " -o " + fixed.string() + " -q", &err), 0) << err;
  const Value fx = load(fixed / "compare.json");
  ASSERT_EQ(fx.at("landmarks_transferred").size(), 2u);
  EXPECT_EQ(fx.at("landmarks_transferred")[0].get<std::string>(), "Go_L");
  EXPECT_EQ(fx.at("landmarks_transferred")[1].get<std::string>(), "Me");
  EXPECT_NEAR(fx.at("landmark_transfer").at("Go_L").at("disagreement_mm").get<double>(), 7.0, 1.0);
  // Same bone: with the transferred landmarks post measures what pre did.
  EXPECT_NEAR(fx.at("bilateral_with_transferred_landmarks").at("gonion_to_plane_mm").at("change").get<double>(), 0.0, 0.5);
  EXPECT_NE(slurp_file(fixed / "compare.html").find("transferred here: Go_L, Me"), std::string::npos);
  ASSERT_EQ(run("compare " + pre.string() + " " + bad.string() + " -o " + fixed.string() + " -q --transfer-landmarks off", &err), 0);
  EXPECT_EQ(load(fixed / "compare.json").at("landmarks_transferred").size(), 0u);
  EXPECT_EQ(run("compare " + pre.string() + " " + bad.string() + " -o " + fixed.string() + " --transfer-landmarks sometimes"), 2);
  fs::remove_all(bad);
  fs::remove_all(fixed);
  // Usage errors.
  EXPECT_EQ(run("compare " + pre.string() + " -o " + same.string()), 2);
  EXPECT_EQ(run("compare " + pre.string() + " /nonexistent/post -o " + same.string()), 3);
  fs::remove_all(pre);
  fs::remove_all(out);
  fs::remove_all(same);
}

}  // namespace

namespace {

// A cohort folder `src` of two sample studies: sym (symmetric) and ramus4.
void link_two_sample_studies(const fs::path& src) {
  const fs::path samples = fs::path(MANDISYM_SOURCE_DIR) / "sample_dicom";
  fs::create_directories(src);
  fs::create_directory_symlink(samples / "symmetric" / "dicom", src / "sym");
  fs::create_directory_symlink(samples / "ramus_L_plus4mm" / "dicom", src / "ramus4");
}

TEST(EndToEnd, BatchRunsEveryStudyRecordsFailuresAndResumes) {
  const fs::path src = temp_dir("batch_src"), out = temp_dir("batch_out");
  const fs::path samples = fs::path(MANDISYM_SOURCE_DIR) / "sample_dicom";
  link_two_sample_studies(src);
  fs::create_directories(src / "not_dicom");
  std::ofstream(src / "not_dicom" / "notes.txt") << "not an image\n";
  std::string err;
  EXPECT_EQ(run("batch " + src.string() + " -o " + out.string() + " --jobs 2 -q", &err), 9) << err;  // one study failed
  auto read = [](const fs::path& p) {
    std::ifstream f(p);
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
  };
  std::string csv = read(out / "cohort.csv");
  EXPECT_NE(csv.find("\"sym\",\"ok\",0,"), std::string::npos) << csv;
  EXPECT_NE(csv.find("\"ramus4\",\"ok\",0,"), std::string::npos) << csv;
  EXPECT_NE(csv.find("\"not_dicom\",\"failed\",4,\"mandisym: error:"), std::string::npos) << csv;
  EXPECT_TRUE(fs::exists(out / "sym" / "report.html"));
  const std::string html = read(out / "cohort.html");
  EXPECT_NE(html.find("href=\"sym/report.html\""), std::string::npos);
  // Resumable: completed studies are not run again, and give the same rows.
  const auto stamp = fs::last_write_time(out / "sym" / "results.json");
  EXPECT_EQ(run("batch " + src.string() + " -o " + out.string() + " -q", &err), 9) << err;
  EXPECT_EQ(fs::last_write_time(out / "sym" / "results.json"), stamp);
  csv = read(out / "cohort.csv");
  EXPECT_NE(csv.find("\"sym\",\"done-earlier\",0,"), std::string::npos) << csv;
  // Deterministic: a fresh run of the same study gives the same numbers.
  const fs::path again = temp_dir("batch_again");
  ASSERT_EQ(run("run " + (samples / "symmetric" / "dicom").string() + " -o " + again.string() + " -q", &err), 0) << err;
  const Value a = load(out / "sym" / "results.json"), b = load(again / "results.json");
  EXPECT_EQ(a.at("scores").dump(), b.at("scores").dump());
  EXPECT_EQ(a.at("landmarks").dump(), b.at("landmarks").dump());
  EXPECT_EQ(a.at("mesh").dump(), b.at("mesh").dump());
  // A CSV list with ids and relative paths.
  std::ofstream(src / "list.csv") << "id,path\nfirst one,sym\n";
  const fs::path out2 = temp_dir("batch_csv");
  EXPECT_EQ(run("batch " + (src / "list.csv").string() + " -o " + out2.string() + " -q", &err), 0) << err;
  EXPECT_TRUE(fs::exists(out2 / "first_one" / "results.json"));
  for (const auto& d : {src, out, again, out2}) fs::remove_all(d);
}

}  // namespace

namespace {

// Invariance: the thread budget (`run --threads`, set per study by `batch`)
// changes the speed, never the numbers.
TEST(EndToEnd, ThreadCountDoesNotChangeTheNumbers) {
  const fs::path in = fs::path(MANDISYM_SOURCE_DIR) / "sample_dicom" / "ramus_L_plus4mm" / "dicom";
  const fs::path one = temp_dir("threads_1"), three = temp_dir("threads_3");
  std::string err;
  ASSERT_EQ(run("run " + in.string() + " -o " + one.string() + " -q --no-figures --threads 1", &err), 0) << err;
  ASSERT_EQ(run("run " + in.string() + " -o " + three.string() + " -q --no-figures --threads 3", &err), 0) << err;
  const Value a = load(one / "results.json"), b = load(three / "results.json");
  for (const char* block : {"segmentation", "qc", "mesh", "landmarks", "symmetry_plane", "cranial_plane", "reference_configuration", "landmark_asymmetry_mm", "scores"})
    if (a.contains(block)) EXPECT_EQ(ms::dump_json(a.at(block)), ms::dump_json(b.at(block))) << block;
  for (const auto& d : {one, three}) fs::remove_all(d);
}

// A study that failed quality control (headsq read upside down: exit 8,
// outputs written) stays `qc_failed` with exit code 8 when the cohort is
// resumed or aggregated, and is not run again.
TEST(EndToEnd, BatchKeepsAQcFailedStudyWhenResumed) {
  if (headsq_nhdr().empty()) GTEST_SKIP() << "shared data not present";
  const fs::path src = temp_dir("batchqc_src"), out = temp_dir("batchqc_out");
  fs::create_directories(src);
  std::ofstream(src / "list.csv") << "id,path\nhq," << headsq_nhdr() << "\n";
  const std::string cmd = "batch " + (src / "list.csv").string() + " -o " + out.string() + " -q -- --hu-offset -1024 --no-figures";
  std::string err;
  ASSERT_EQ(run(cmd, &err), 9) << err;
  const auto stamp = fs::last_write_time(out / "hq" / "results.json");
  const std::string aggregate = "batch " + (src / "list.csv").string() + " -o " + out.string() + " -q --aggregate-only";
  for (const std::string& again : {cmd, aggregate}) {
    EXPECT_EQ(run(again, &err), 9) << err;
    std::ifstream f(out / "cohort.csv");
    std::string header, row;
    std::getline(f, header), std::getline(f, row);
    EXPECT_EQ(row.rfind("\"hq\",\"qc_failed\",8,", 0), 0u) << again << ": " << row;
    EXPECT_NE(row.find("--hu-offset -1024 --no-figures"), std::string::npos) << again << ": the options its run was given: " << row;
  }
  EXPECT_EQ(fs::last_write_time(out / "hq" / "results.json"), stamp) << "a QC-failed study was run again";
  for (const auto& d : {src, out}) fs::remove_all(d);
}

// `batch SRC -o OUT -- RUN OPTIONS`: the options after `--` reach every
// study's run, a CSV's per-study columns override them, and cohort.csv records
// what each study was given; bad options are refused before any study starts.
TEST(EndToEnd, BatchPassesRunOptionsAndCsvColumnsOverrideThem) {
  const fs::path src = temp_dir("batchopt_src"), out = temp_dir("batchopt_out");
  link_two_sample_studies(src);
  std::ofstream(src / "list.csv") << "id,path,hu_offset,orientation,group\nsym,sym,,,control\nramus4,ramus4,5,,case\n";
  const std::string list = (src / "list.csv").string();
  std::string err;
  // Refused before anything runs: unknown or batch-owned options, bad values.
  for (const std::string bad : {"-- --bogus 1", "-- --threads 3", "-- -o elsewhere", "-- --bone-threshold 99999", "--jobs 1.5",
                                "--jobs 0", "--threads-per-job 0", "-- extra_argument"})
    EXPECT_EQ(run("batch " + list + " -o " + out.string() + " -q " + bad, &err), 2) << bad << ": " << err;
  EXPECT_FALSE(fs::exists(out / "sym")) << "a study ran despite bad options";
  std::ofstream(src / "bad.csv") << "id,path,label\nsym,sym,3\n";  // --label without --mask
  EXPECT_EQ(run("batch " + (src / "bad.csv").string() + " -o " + out.string() + " -q", &err), 4) << err;
  EXPECT_NE(err.find("study sym"), std::string::npos) << err;

  ASSERT_EQ(run("batch " + list + " -o " + out.string() + " -q --jobs auto -- --bone-threshold 260 --no-figures", &err), 0) << err;
  const Value sym = load(out / "sym" / "results.json"), ramus = load(out / "ramus4" / "results.json");
  EXPECT_EQ(sym.at("parameters").at("bone_threshold_hu").get<double>(), 260);
  EXPECT_EQ(sym.at("parameters").at("hu_offset").get<double>(), 0);
  EXPECT_EQ(ramus.at("parameters").at("bone_threshold_hu").get<double>(), 260);
  EXPECT_EQ(ramus.at("parameters").at("hu_offset").get<double>(), 5);
  EXPECT_TRUE(fs::is_empty(out / "sym" / "qc")) << "--no-figures did not reach the run";
  std::ifstream f(out / "cohort.csv");
  std::string header, row1, row2;
  std::getline(f, header), std::getline(f, row1), std::getline(f, row2);
  EXPECT_EQ(header.rfind("id,status,exit_code,error,signal,seconds,peak_memory_mb,options,", 0), 0u) << header;
  EXPECT_NE(row1.find("--bone-threshold 260 --no-figures\""), std::string::npos) << row1;
  EXPECT_NE(row2.find("--bone-threshold 260 --no-figures --hu-offset 5\""), std::string::npos) << row2;
  EXPECT_NE(row1.find("--threads "), std::string::npos) << row1;
  EXPECT_NE(header.find(",qc_status,saf_band,mirror_p95_band,menton_deviation_mm,menton_band,menton_measured_from"), std::string::npos)
      << header;
  EXPECT_NE(row1.find(",pass,"), std::string::npos) << row1;
  EXPECT_TRUE(row1.find(",cranial_plane") != std::string::npos || row1.find(",mandible_plane") != std::string::npos) << row1;
  // The `group` column: cohort_groups.csv and the Groups section of cohort.html.
  std::ifstream g(out / "cohort_groups.csv");
  std::string gh, g1;
  std::getline(g, gh), std::getline(g, g1);
  EXPECT_EQ(gh.rfind("score,group_a,group_b,n_a,n_b,median_a,", 0), 0u) << gh;
  EXPECT_EQ(g1.rfind("\"saf_score\",\"case\",\"control\",1,1,", 0), 0u) << g1;
  std::ifstream hf(out / "cohort.html");
  const std::string html((std::istreambuf_iterator<char>(hf)), std::istreambuf_iterator<char>());
  EXPECT_NE(html.find("<h2>Groups</h2>"), std::string::npos);
  EXPECT_NE(html.find(">studies</text>"), std::string::npos) << "histograms without a count axis";
  for (const auto& d : {src, out}) fs::remove_all(d);
}

}  // namespace

namespace {

// Every number of a results.json by its path ("scores.saf.score",
// "landmarks.Co_L[0]"), booleans and strings left out.
void numbers_of(const Value& v, const std::string& path, std::map<std::string, double>& out) {
  if (v.is_number()) out[path] = v.get<double>();
  if (v.is_array())
    for (std::size_t i = 0; i < v.size(); ++i) numbers_of(v[i], path + "[" + std::to_string(i) + "]", out);
  if (v.is_object())
    for (const auto& [k, x] : v.items()) numbers_of(x, path.empty() ? k : path + "." + k, out);
}

// N, issue "same scan, same answer": one scan stored five ways (its DICOM
// series; NIfTI with the rows and columns reversed, RAS; NIfTI with the rows
// reversed, LAS; NRRD and MetaImage with the slices reversed) gives the same
// results.json numbers, because ingest brings every grid to one array order
// (core/array_order.h). Before, the sample as dcm2niix's NIfTI gave another
// SAF score (0.02041 vs 0.02094) and another largest region. Timings and the
// input block (the file's own size/direction) are left out.
TEST(EndToEnd, OneScanStoredFiveWaysGivesIdenticalNumbers) {
  const fs::path dir = temp_dir("five_ways");
  fs::create_directories(dir);
  const fs::path series = kSamples / "symmetric" / "dicom";
  const ms::io::LoadedScan scan = ms::io::read_scan(series.string());
  struct Storage {
    std::string name;
    ms::AxisReorder order;
  };
  auto flips = [](bool i, bool j, bool k) {
    ms::AxisReorder r;
    r.flip = {i, j, k};
    return r;
  };
  const std::vector<Storage> storages{{"ras.nii.gz", flips(true, true, false)}, {"las.nii.gz", flips(false, true, false)},
                                      {"sli.nrrd", flips(false, false, true)}, {"kji.mha", [] {
                                         ms::AxisReorder r;
                                         r.from = {2, 1, 0};
                                         return r;
                                       }()}};
  std::vector<fs::path> inputs{series};
  for (const Storage& s : storages) {
    ms::Volume v;
    v.geom = ms::reordered(scan.volume.geom, s.order);
    v.hu = ms::reordered_values(scan.volume.hu, scan.volume.geom, s.order);
    ASSERT_FALSE(ms::canonical_reorder(v.geom).identity()) << s.name << " is stored in the canonical order already";
    ms::io::write_volume(v, (dir / s.name).string());
    inputs.push_back(dir / s.name);
  }
  std::map<std::string, double> reference;
  for (std::size_t n = 0; n < inputs.size(); ++n) {
    const fs::path out = dir / ("out" + std::to_string(n));
    std::string err;
    ASSERT_EQ(run("run " + inputs[n].string() + " -o " + out.string() + " -q --no-figures --no-cranial", &err), 0)
        << inputs[n] << ": " << err;
    std::map<std::string, double> numbers;
    numbers_of(load(out / "results.json"), "", numbers);
    for (auto it = numbers.begin(); it != numbers.end();)
      it = (it->first.rfind("timings_s", 0) == 0 || it->first.rfind("input.", 0) == 0) ? numbers.erase(it) : std::next(it);
    if (n == 0) {
      reference = numbers;
      ASSERT_GT(reference.count("scores.saf.score"), 0u);
      continue;
    }
    SCOPED_TRACE(inputs[n].filename().string());
    EXPECT_EQ(numbers.size(), reference.size());
    std::size_t differ = 0;
    for (const auto& [k, x] : reference) {
      const auto it = numbers.find(k);
      if (it == numbers.end() || it->second != x) {
        if (++differ <= 10) ADD_FAILURE() << k << ": " << x << " from DICOM, " << (it == numbers.end() ? NAN : it->second);
      }
    }
    EXPECT_EQ(differ, 0u);
  }
  fs::remove_all(dir);
}

}  // namespace

namespace {

// Output of a shell command (stdout and stderr), "" when it cannot run.
std::string shell_output(const std::string& cmd) {
  std::string out;
  if (FILE* p = ::popen((cmd + " 2>&1").c_str(), "r")) {
    char buf[4096];
    while (std::size_t n = std::fread(buf, 1, sizeof buf, p)) out.append(buf, n);
    ::pclose(p);
  }
  return out;
}

bool have(const std::string& tool) { return std::system(("command -v " + tool + " > /dev/null 2>&1").c_str()) == 0; }

// N, "the phantom's DICOM": series- and study-level attributes are the same on
// every slice, so dcm2niix makes one volume of each series (it made 26 of the
// sample: every slice had its own library-stamped StudyTime), and dciodvfy
// (dicom3tools) finds no error against the CT Image IOD.
TEST(EndToEnd, WrittenSeriesAreOneVolumeForDcm2niixAndValidCtImages) {
  if (!have("dcm2niix")) GTEST_SKIP() << "dcm2niix not installed (scripts/install-deps installs it)";
  const fs::path dir = temp_dir("dcm2niix");
  fs::create_directories(dir);
  ASSERT_EQ(run("phantom -o " + (dir / "phantom").string() + " --spacing 2 --yaw 5 --no-preview"), 0);
  for (const fs::path& series : {kSamples / "symmetric" / "dicom", kSamples / "ramus_L_plus4mm" / "dicom", dir / "phantom" / "dicom"}) {
    SCOPED_TRACE(series.string());
    const fs::path out = dir / ("nii_" + std::to_string(std::hash<std::string>{}(series.string())));
    fs::create_directories(out);
    const std::string log = shell_output("dcm2niix -z n -f v -o " + out.string() + " " + series.string());
    std::size_t volumes = 0, files = 0;
    for (const auto& e : fs::directory_iterator(out)) volumes += e.path().extension() == ".nii";
    for (const auto& e : fs::directory_iterator(series)) files += e.is_regular_file();
    EXPECT_EQ(volumes, 1u) << log;
    EXPECT_NE(log.find("Convert " + std::to_string(files) + " DICOM"), std::string::npos) << log;
    if (!have("dciodvfy")) continue;
    for (const auto& e : fs::directory_iterator(series)) {
      const std::string v = shell_output("dciodvfy " + e.path().string());
      EXPECT_NE(v.find("CTImage"), std::string::npos) << v;
      EXPECT_EQ(v.find("\nError"), std::string::npos) << e.path() << ":\n" << v;
      EXPECT_NE(v.rfind("Error", 0), 0u) << v;
      break;  // one slice per series: the attributes are written alike
    }
  }
  fs::remove_all(dir);
}

}  // namespace

namespace {

// N: docs/report.md said the ramus sample was "marked" where results.json
// said "mild". Its table of the samples' headline numbers and bands is held
// here to a real run: every number must equal the run's, rounded as printed,
// and every band must be the run's.
TEST(EndToEnd, ReportDocsAgreeWithTheSamples) {
  std::ifstream f(fs::path(MANDISYM_SOURCE_DIR) / "docs" / "report.md");
  std::string line;
  std::map<std::string, std::vector<std::string>> rows;
  while (std::getline(f, line)) {
    for (const char* sample : {"symmetric", "ramus_L_plus4mm"})
      if (line.rfind(std::string("| ") + sample + " |", 0) == 0) {
        std::vector<std::string> cells;
        std::stringstream ss(line);
        std::string cell;
        while (std::getline(ss, cell, '|')) {
          const auto a = cell.find_first_not_of(' '), b = cell.find_last_not_of(' ');
          if (a != std::string::npos) cells.push_back(cell.substr(a, b - a + 1));
        }
        rows[sample] = cells;
      }
  }
  ASSERT_EQ(rows.size(), 2u) << "docs/report.md has no table of the samples";
  for (const auto& [sample, cells] : rows) {
    SCOPED_TRACE(sample);
    ASSERT_EQ(cells.size(), 8u);
    const fs::path out = temp_dir("docs_" + sample);
    std::string err;
    ASSERT_EQ(run("run " + (kSamples / sample / "dicom").string() + " -o " + out.string() + " -q --no-figures", &err), 0) << err;
    const Value r = load(out / "results.json");
    const Value &s = r.at("scores"), &i = r.at("interpretation");
    auto same = [](const std::string& printed, double value) {
      const auto dot = printed.find('.');
      const int decimals = dot == std::string::npos ? 0 : static_cast<int>(printed.size() - dot - 1);
      return std::abs(std::stod(printed) - value) <= 0.5 * std::pow(10.0, -decimals) + 1e-12;
    };
    EXPECT_TRUE(same(cells[1], s.at("saf").at("score").get<double>())) << cells[1] << " vs " << s.at("saf").at("score").get<double>();
    EXPECT_EQ(cells[2], i.at("saf_score").at("band").get<std::string>());
    const double ramus = s.at("bilateral").at("ramus_height_mm").at("diff").get<double>();
    EXPECT_TRUE(same(cells[3], ramus)) << cells[3] << " vs " << ramus;
    EXPECT_TRUE(same(cells[4], i.at("ramus_height").at("value").get<double>())) << cells[4];
    EXPECT_EQ(cells[5], i.at("ramus_height").at("band").get<std::string>());
    EXPECT_TRUE(same(cells[6], s.at("mirror").at("p95_mm").get<double>())) << cells[6];
    EXPECT_EQ(cells[7], i.at("mirror_distance").at("band").get<std::string>());
    fs::remove_all(out);
  }
}

}  // namespace

namespace {

// N: `-h` works on every verb (it was a usage error, exit 2), as --help.
TEST(EndToEnd, EveryVerbHasHelp) {
  for (const char* verb : {"run", "batch", "compare", "inspect", "phantom"})
    for (const char* flag : {"-h", "--help"}) {
      SCOPED_TRACE(std::string(verb) + " " + flag);
      std::string err;
      EXPECT_EQ(run(std::string(verb) + " " + flag, &err), 0) << err;
    }
  // Options with a range show it, as run_settings enforces it.
  const std::string help = shell_output(kBin + " run --help");
  EXPECT_NE(help.find("--disk-radius MM"), std::string::npos) << help;
  EXPECT_NE(help.find("(default: 2) [0.1 to 10]"), std::string::npos) << help;
  EXPECT_NE(help.find("(default: 250) [-1000 to 3000]"), std::string::npos) << help;
}

}  // namespace
