// End to end: `mandisym compare` and `mandisym batch` against hostile inputs.
//
// Run folders are made by the real binary (`mandisym run` on the bundled
// samples and on a generated phantom, once each, shared by the tests) and then
// copied and edited the way an attacker or a careless hand would. The
// contract checked (README.md "Exit codes", docs/batch.md):
//   compare:
//   1. a results.json / srd.json field of the wrong type, a non-finite or
//      absurd (beyond 10 m) coordinate: exit 4, stderr exactly one line
//      "mandisym: error: FILE: field `PATH`: ..." naming the file and the field;
//      never exit 1, never a hang (a guard kills the binary after kGuardS);
//   2. POST dated before PRE, or another patient's mandible (volume ratio,
//      ramus landmarks after rigid alignment): exit 0, a warning on stderr and
//      in compare.json `warnings` / `warning_details` with its evidence; a
//      de-identified run's identifiers are never printed;
//   batch:
//   3. --deidentify: no input path and no patient-like name of a study
//      reaches any file under OUT;
//   4. a study that hangs is killed after --study-timeout and recorded as
//      `timeout` with its seconds, one killed by a signal as `killed` with
//      that signal, and the cohort goes on.
// MANDISYM_BINARY_UNDER_TEST=/path/to/mandisym runs the suite against another
// build (e.g. the one before a fix, to see the tests fail).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "core/json_text.h"
#include "tests/support/binary_run.h"

namespace fs = std::filesystem;
using Value = ms::Json;
using ms::json_numbers;
using ms::parse_json;

namespace {

using ms::testing::describe;
using ms::testing::record_case;
using ms::testing::slurp;
using ms::testing::RunLimits;
using ms::testing::RunResult;

const fs::path kSamples = fs::path(MANDISYM_SOURCE_DIR) / "sample_dicom";
// Guard, s: a binary still running after this is killed and the case fails
// (the defects were a 290 s hang and a cohort blocked for ever).
constexpr int kGuardS = 120;

fs::path root() {
  static const fs::path r = [] {
    fs::path p = fs::temp_directory_path() / ("mandisym_hbc_" + std::to_string(::getpid()));
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
  }();
  return r;
}

Value load(const fs::path& p) { return parse_json(slurp(p)); }
void save(const fs::path& p, const Value& v) { std::ofstream(p) << v.dump(2); }

// The shared runner (tests/support/binary_run.h) with this suite's guard.
RunLimits guarded() {
  RunLimits l;
  l.guard_seconds = kGuardS;
  return l;
}

RunResult run(const std::vector<std::string>& args) { return ms::testing::run_binary(args, root() / "cmd", guarded()); }

// One `mandisym run` per fixture, shared by the tests.
const fs::path& run_folder(const std::string& name, const std::vector<std::string>& args) {
  static std::map<std::string, fs::path> cache;
  auto it = cache.find(name);
  if (it != cache.end()) return it->second;
  const fs::path out = root() / ("run_" + name);
  std::vector<std::string> a = {"run"};
  a.insert(a.end(), args.begin(), args.end());
  a.insert(a.end(), {"-o", out.string(), "-q", "--no-figures"});
  const RunResult r = run(a);
  EXPECT_EQ(r.code, 0) << name << ": " << describe(r);
  return cache[name] = out;
}
const fs::path& pre_run() { return run_folder("pre", {(kSamples / "symmetric" / "dicom").string()}); }
// The same head with the left ramus 4 mm taller: what a surgery could change.
const fs::path& post_run() { return run_folder("post", {(kSamples / "ramus_L_plus4mm" / "dicom").string()}); }
const fs::path& deidentified_run() {
  return run_folder("deid", {(kSamples / "ramus_L_plus4mm" / "dicom").string(), "--deidentify"});
}
// Another person: the phantom's adult at 0.8 of its size (docs/phantom.md
// `--scale`; bicondylar width ~82 mm instead of ~102 mm).
const fs::path& other_patient_run() {
  static const fs::path ph = [] {
    const fs::path p = root() / "other_phantom";
    const RunResult r = run({"phantom", "-o", p.string(), "--spacing", "1", "--fov", "140,120,120", "--scale", "0.8", "--no-preview"});
    EXPECT_EQ(r.code, 0) << describe(r);
    return p;
  }();
  return run_folder("other", {(ph / "dicom").string()});
}

// A copy of a run folder (results.json, mandible.vtp, srd.json) with edits.
fs::path edited(const fs::path& run, const std::string& name, const std::function<void(Value&)>& results,
                const std::function<void(Value&)>& srd = nullptr) {
  const fs::path d = root() / ("edit_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  for (const char* f : {"results.json", "mandible.vtp", "srd.json"}) fs::copy_file(run / f, d / f);
  Value r = load(d / "results.json");
  if (results) results(r);
  save(d / "results.json", r);
  if (srd) {
    Value s = load(d / "srd.json");
    srd(s);
    save(d / "srd.json", s);
  }
  return d;
}

// Checks exit 4 and one stderr line naming the file and the field.
// Also a corpus case (category compare), within its budget.
void expect_invalid(const RunResult& r, const fs::path& file, const std::string& field) {
  record_case(r, 4, "compare");
  EXPECT_FALSE(r.guard_killed) << describe(r);
  EXPECT_EQ(r.code, 4) << describe(r);
  EXPECT_EQ(r.err.rfind("mandisym: error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find(file.string()), std::string::npos) << "does not name " << file << ": " << r.err;
  EXPECT_NE(r.err.find("`" + field + "`"), std::string::npos) << "does not name field " << field << ": " << r.err;
}

RunResult compare(const fs::path& pre, const fs::path& post, const fs::path& out) {
  return run({"compare", pre.string(), post.string(), "-o", out.string(), "-q", "--transfer-landmarks", "off"});
}

// The warning_details entry with that code (null Value when absent).
Value warning(const Value& c, const std::string& code) {
  if (const Value* d = ms::find_member(c, "warning_details"))
    for (const auto& w : *d)
      if (w.at("code").get<std::string>() == code) return w;
  return Value();
}

// ---------------------------------------------------------------- compare

// Defect 1: wrong JSON types gave exit 1 "internal error".
TEST(HostileCompare, MistypedFieldsAreInvalidInputNamingFileAndField) {
  const fs::path pre = pre_run(), out = root() / "cmp_types";
  struct Case {
    std::string name, file, field;
    std::function<void(Value&)> results, srd;
  };
  const std::vector<Case> cases = {
      {"string_coordinate", "results.json", "landmarks.Co_L[0]", [](Value& r) { r["landmarks"]["Co_L"][0] = Value("51"); }},
      {"landmarks_array", "results.json", "landmarks", [](Value& r) { r["landmarks"] = Value::array(); }},
      {"landmark_object", "results.json", "landmarks.Go_R", [](Value& r) { r["landmarks"]["Go_R"] = Value::object(); }},
      {"normal_object", "results.json", "symmetry_plane.normal",
       [](Value& r) { r["symmetry_plane"]["normal"] = Value::object(); }},
      {"plane_missing", "results.json", "symmetry_plane", [](Value& r) { r["symmetry_plane"] = Value(); }},
      {"score_string", "results.json", "scores.saf.score", [](Value& r) { r["scores"]["saf"]["score"] = Value("high"); }},
      {"scores_saf_string", "results.json", "scores.saf", [](Value& r) { r["scores"]["saf"] = Value("x"); }},
      {"study_date_number", "results.json", "input.study_date", [](Value& r) { r["input"]["study_date"] = Value(20260101); }},
      {"srd_bins_string", "srd.json", "bins", nullptr, [](Value& s) { s["bins"] = Value("12"); }},
      {"srd_bins_zero", "srd.json", "bins", nullptr, [](Value& s) { s["bins"] = Value(0); }},
      {"srd_blocks_object", "srd.json", "landmarks.Co_L", nullptr, [](Value& s) { s["landmarks"]["Co_L"] = Value::object(); }},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const fs::path bad = edited(pre, c.name, c.results, c.srd);
    expect_invalid(compare(pre, bad, out), bad / c.file, c.field);
    expect_invalid(compare(bad, pre, out), bad / c.file, c.field);  // as PRE too
  }
}

// Defect 2: landmarks at 1e300 kept align_rigid busy for 290 s.
TEST(HostileCompare, NonFiniteOrAbsurdCoordinatesAreRefusedAtOnce) {
  const fs::path pre = pre_run(), out = root() / "cmp_huge";
  const fs::path huge = edited(pre, "huge", [](Value& r) {
    Value lm = Value::object();
    for (const auto& [name, p] : r.at("landmarks").items()) lm[name] = json_numbers(std::vector<double>{1e300, -1e300, 1e300});
    r["landmarks"] = lm;
  });
  expect_invalid(compare(pre, huge, out), huge / "results.json", "landmarks.Co_L[0]");
  // 20 m: finite, but no patient coordinate is that far from the scanner.
  const fs::path far = edited(pre, "far", [](Value& r) { r["symmetry_plane"]["point"][1] = Value(2.0e4); });
  expect_invalid(compare(far, pre, out), far / "results.json", "symmetry_plane.point[1]");
  const fs::path zero = edited(pre, "zero_normal", [](Value& r) {
    r["symmetry_plane"]["normal"] = json_numbers(std::vector<double>{0, 0, 0});
  });
  expect_invalid(compare(pre, zero, out), zero / "results.json", "symmetry_plane.normal");
  EXPECT_FALSE(fs::exists(out / "compare.json"));
}

// Defect 3: POST dated before PRE.
TEST(HostileCompare, PostDatedBeforePreIsWarnedWithBothDates) {
  const fs::path pre = pre_run(), out = root() / "cmp_dates";
  const std::string pre_date = load(pre / "results.json").at("input").at("study_date").get<std::string>();
  ASSERT_EQ(pre_date.size(), 8u);
  const std::string earlier = std::to_string(std::stoi(pre_date.substr(0, 4)) - 1) + pre_date.substr(4);
  const fs::path post = edited(post_run(), "earlier", [&](Value& r) { r["input"]["study_date"] = Value(earlier); });
  const RunResult r = compare(pre, post, out);
  record_case(r, 0, "compare");
  ASSERT_EQ(r.code, 0) << describe(r);
  EXPECT_NE(r.err.find("mandisym: warning: POST's study date " + earlier + " is before PRE's " + pre_date), std::string::npos) << r.err;
  const Value c = load(out / "compare.json");
  const Value w = warning(c, "post_dated_before_pre");
  ASSERT_FALSE(w.is_null()) << c.dump(2);
  EXPECT_EQ(w.at("evidence").at("pre_study_date").get<std::string>(), pre_date);
  EXPECT_EQ(w.at("evidence").at("post_study_date").get<std::string>(), earlier);
  bool listed = false;
  for (const auto& s : c.at("warnings")) listed |= s.get<std::string>() == w.at("message").get<std::string>();
  EXPECT_TRUE(listed) << "warning_details and warnings disagree";
}

// Defect 3: another patient's mandible gives a shape warning with the
// evidence; the same patient before/after a 4 mm ramus change gives none.
TEST(HostileCompare, AnotherPatientsMandibleIsWarnedAndTheSamePatientIsNot) {
  const fs::path same = root() / "cmp_same_patient", other = root() / "cmp_other_patient";
  RunResult r = compare(pre_run(), post_run(), same);
  record_case(r, 0, "compare");
  ASSERT_EQ(r.code, 0) << describe(r);
  const Value s = load(same / "compare.json");
  EXPECT_TRUE(warning(s, "mandible_volume_ratio").is_null()) << s.at("consistency").dump(2);
  EXPECT_TRUE(warning(s, "ramus_configuration").is_null()) << s.at("consistency").dump(2);
  EXPECT_TRUE(warning(s, "post_dated_before_pre").is_null());
  const Value& shape = s.at("consistency").at("shape");
  EXPECT_LT(shape.at("volume_ratio").get<double>(), shape.at("volume_ratio_max").get<double>());
  EXPECT_LT(shape.at("ramus_rms_mm").get<double>(), shape.at("ramus_rms_max_mm").get<double>());

  r = compare(pre_run(), other_patient_run(), other);
  record_case(r, 0, "compare");
  ASSERT_EQ(r.code, 0) << describe(r);
  const Value o = load(other / "compare.json");
  const Value w = warning(o, "mandible_volume_ratio");
  ASSERT_FALSE(w.is_null()) << o.at("consistency").dump(2);
  EXPECT_GT(w.at("evidence").at("ratio").get<double>(), w.at("evidence").at("max_ratio").get<double>());
  EXPECT_GT(w.at("evidence").at("pre_volume_cm3").get<double>(), w.at("evidence").at("post_volume_cm3").get<double>());
  EXPECT_NE(r.err.find("mandisym: warning: mandible volumes differ"), std::string::npos) << r.err;
  const Value rw = warning(o, "ramus_configuration");
  ASSERT_FALSE(rw.is_null()) << o.at("consistency").dump(2);
  EXPECT_GT(rw.at("evidence").at("ramus_rms_mm").get<double>(), rw.at("evidence").at("max_mm").get<double>());
}

// Defect 3: identifiers of a de-identified comparison are never printed.
TEST(HostileCompare, DeidentifiedRunsAreNotComparedByIdentifiersNorPrinted) {
  const fs::path out = root() / "cmp_deid";
  const Value pre = load(pre_run() / "results.json");
  const std::string uid = pre.at("input").at("series_uid").get<std::string>(), date = pre.at("input").at("study_date").get<std::string>();
  const RunResult r = compare(pre_run(), deidentified_run(), out);
  record_case(r, 0, "compare");
  ASSERT_EQ(r.code, 0) << describe(r);
  const Value c = load(out / "compare.json");
  EXPECT_FALSE(c.at("consistency").at("identity").at("compared").get<bool>());
  for (const std::string& text : {r.err, slurp(out / "compare.json"), slurp(out / "compare.html")})
    for (const std::string& secret : {uid, date}) EXPECT_EQ(text.find(secret), std::string::npos) << secret;
}

// ---------------------------------------------------------------- batch

// cohort.csv as id -> column -> value.
std::map<std::string, std::map<std::string, std::string>> read_cohort(const fs::path& csv) {
  auto split = [](const std::string& line) {
    std::vector<std::string> out;
    std::string cur;
    bool q = false;
    for (std::size_t i = 0; i < line.size(); ++i) {
      const char c = line[i];
      if (q && c == '"' && i + 1 < line.size() && line[i + 1] == '"') cur += '"', ++i;
      else if (c == '"') q = !q;
      else if (c == ',' && !q) out.push_back(cur), cur.clear();
      else cur += c;
    }
    out.push_back(cur);
    return out;
  };
  std::ifstream f(csv);
  std::string line;
  std::map<std::string, std::map<std::string, std::string>> rows;
  if (!std::getline(f, line)) return rows;
  const auto head = split(line);
  while (std::getline(f, line)) {
    const auto v = split(line);
    for (std::size_t i = 0; i < head.size() && i < v.size(); ++i) rows[v[0]][head[i]] = v[i];
  }
  return rows;
}

// Defect 4: a failing study's error line carried the patient-named path into
// cohort.csv, cohort.html and .logs/.
TEST(HostileBatch, DeidentifyKeepsPatientNamedPathsOutOfEveryCohortFile) {
  const fs::path src = root() / "deid_src", out = root() / "deid_out";
  fs::create_directories(src / "DOE^JOHN_12345");
  std::ofstream(src / "DOE^JOHN_12345" / "notes.txt") << "not an image\n";
  fs::create_directory_symlink(kSamples / "symmetric" / "dicom", src / "ROE^JANE_67890");
  const RunResult r = run({"batch", src.string(), "-o", out.string(), "--deidentify", "-q"});
  record_case(r, 9, "batch");
  ASSERT_FALSE(r.guard_killed);
  EXPECT_EQ(r.code, 9) << describe(r);
  const auto rows = read_cohort(out / "cohort.csv");
  ASSERT_EQ(rows.size(), 2u) << slurp(out / "cohort.csv");
  std::size_t failed = 0;
  for (const auto& [id, row] : rows) {
    if (row.at("status") == "failed") {
      ++failed;
      EXPECT_EQ(row.at("exit_code"), "4");
      EXPECT_NE(row.at("error").find(id), std::string::npos) << "the path is not replaced by the id: " << row.at("error");
    } else {
      EXPECT_EQ(row.at("status"), "ok") << row.at("error");
    }
  }
  EXPECT_EQ(failed, 1u);
  std::size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(out)) {
    const std::string name = e.path().string().substr(out.string().size());
    for (const std::string& secret : {std::string("DOE^JOHN"), std::string("DOE_JOHN"), std::string("ROE^JANE"),
                                      std::string("ROE_JANE"), std::string("JOHN_12345"), src.string()})
      EXPECT_EQ(name.find(secret), std::string::npos) << "file name " << e.path();
    if (!e.is_regular_file()) continue;
    ++files;
    const std::string text = slurp(e.path());
    for (const std::string& secret : {std::string("DOE^JOHN"), std::string("DOE_JOHN"), std::string("ROE^JANE"),
                                      std::string("ROE_JANE"), std::string("JOHN_12345"), src.string()})
      EXPECT_EQ(text.find(secret), std::string::npos) << e.path() << " contains " << secret;
  }
  EXPECT_GT(files, 5u);
  // Resumable under the same key: the completed study is not run again.
  const RunResult again = run({"batch", src.string(), "-o", out.string(), "--deidentify", "-q"});
  record_case(again, 9, "batch");
  EXPECT_EQ(again.code, 9) << describe(again);
  std::size_t earlier = 0;
  for (const auto& [id, row] : read_cohort(out / "cohort.csv")) earlier += row.at("status") == "done-earlier";
  EXPECT_EQ(earlier, 1u) << slurp(out / "cohort.csv");
}

// The pid of a running `mandisym run` child of `parent` whose command line
// holds `needle` (0 when none yet).
pid_t find_child(pid_t parent, const std::string& needle) {
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string n = e.path().filename().string();
    if (n.find_first_not_of("0123456789") != std::string::npos) continue;
    std::string stat = slurp(e.path() / "stat");
    const std::size_t rp = stat.rfind(')');
    if (rp == std::string::npos) continue;
    std::istringstream s(stat.substr(rp + 2));
    char state = 0;
    long ppid = 0;
    s >> state >> ppid;
    if (ppid != parent) continue;
    std::string cmd = slurp(e.path() / "cmdline");
    std::replace(cmd.begin(), cmd.end(), '\0', ' ');
    if (cmd.find(" run ") != std::string::npos && cmd.find(needle) != std::string::npos) return static_cast<pid_t>(std::stol(n));
  }
  return 0;
}

// Waits (up to kGuardS, while the parent lives) for that child and sends it
// `sig`; false if it never appeared.
bool signal_child(pid_t parent, const std::string& needle, int sig) {
  const auto t0 = std::chrono::steady_clock::now();
  const fs::path parent_stat = fs::path("/proc") / std::to_string(parent) / "stat";
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(kGuardS)) {
    const std::string st = slurp(parent_stat);
    if (st.empty() || st.find(") Z ") != std::string::npos) return false;  // the batch ended (e.g. refused the options)
    if (const pid_t c = find_child(parent, needle)) return ::kill(c, sig) == 0;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return false;
}

// Defects 5 and 6: a study that hangs blocked the cohort for ever (no
// timeout); a study killed by a signal was "failed" with exit code 128+N.
// The hang is real: the test stops the study's process (SIGSTOP), as a
// process stuck on a dead network mount would be; the batch must kill it.
TEST(HostileBatch, HungStudyTimesOutKilledStudyIsRecordedAndTheCohortGoesOn) {
  const fs::path src = root() / "hang_src", out = root() / "hang_out";
  fs::create_directories(src / "not_a_scan");
  std::ofstream(src / "not_a_scan" / "notes.txt") << "not an image\n";
  ASSERT_EQ(::mkfifo((src / "fifo").c_str(), 0644), 0);
  fs::create_directory_symlink(kSamples / "symmetric" / "dicom", src / "hung");
  fs::create_directory_symlink(kSamples / "ramus_L_plus4mm" / "dicom", src / "victim");
  for (const char* bad : {"-1", "soon"}) {
    const RunResult usage = run({"batch", src.string(), "-o", out.string(), "--study-timeout", bad});
    record_case(usage, 2, "batch");
    EXPECT_EQ(usage.code, 2) << describe(usage);
  }

  ms::testing::Child child =
      ms::testing::start_binary({"batch", src.string(), "-o", out.string(), "--jobs", "4", "--study-timeout", "3", "-q"},
                                root() / "batch_hang", guarded());
  const pid_t batch = child.pid;
  const bool stopped = signal_child(batch, (src / "hung").string(), SIGSTOP);
  const bool killed = signal_child(batch, (src / "victim").string(), SIGKILL);
  const RunResult r = ms::testing::wait_binary(child);
  record_case(r, 9, "batch");
  ASSERT_TRUE(stopped && killed) << "the studies' processes were not found";
  ASSERT_FALSE(r.guard_killed) << "the cohort is blocked by the hung study";
  EXPECT_EQ(r.code, 9) << describe(r);
  auto rows = read_cohort(out / "cohort.csv");
  const std::string csv = slurp(out / "cohort.csv");
  ASSERT_EQ(rows.size(), 4u) << csv;
  EXPECT_EQ(rows["hung"]["status"], "timeout") << csv;
  EXPECT_EQ(rows["hung"]["exit_code"], "") << csv;
  EXPECT_FALSE(rows["hung"]["seconds"].empty()) << csv;
  EXPECT_EQ(rows["victim"]["status"], "killed") << csv;
  EXPECT_EQ(rows["victim"]["signal"], std::to_string(SIGKILL)) << csv;
  EXPECT_EQ(rows["victim"]["exit_code"], "") << csv;
  EXPECT_EQ(rows["not_a_scan"]["status"], "failed") << csv;
  EXPECT_EQ(rows["not_a_scan"]["exit_code"], "4") << csv;
  // The FIFO never blocks the cohort: refused by ingest (4) or timed out.
  EXPECT_TRUE(rows["fifo"]["status"] == "timeout" || (rows["fifo"]["status"] == "failed" && rows["fifo"]["exit_code"] == "4")) << csv;
  const std::string html = slurp(out / "cohort.html");
  EXPECT_NE(html.find("timeout: no result within --study-timeout 3 s"), std::string::npos);
  EXPECT_NE(html.find("killed: killed by signal 9"), std::string::npos);
}

// Removes the scratch folder after the suite (MANDISYM_KEEP_BAD_INPUT=1 keeps it).
class Cleanup : public ::testing::Environment {
 public:
  void TearDown() override {
    if (!std::getenv("MANDISYM_KEEP_BAD_INPUT")) fs::remove_all(root());
  }
};
const auto* const kCleanup = ::testing::AddGlobalTestEnvironment(new Cleanup);

}  // namespace
