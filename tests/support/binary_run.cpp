#include "tests/support/binary_run.h"

#include <gtest/gtest.h>
#include <fcntl.h>
#include <grp.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <iterator>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <thread>

#include "core/json_text.h"

namespace fs = std::filesystem;

namespace ms::testing {
namespace {

const std::string kPrefix = "mandisym: error: ";

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}


// SCRATCH.stderr next to scratch; in the temp folder when scratch's folder is
// not one (an OUTDIR under a regular file).
fs::path stderr_file_for(const fs::path& scratch) {
  static int serial = 0;
  std::error_code ec;
  const fs::path dir = scratch.parent_path();
  if (!dir.empty() && fs::is_directory(dir, ec)) return dir / (scratch.filename().string() + ".stderr");
  return fs::temp_directory_path() / ("mandisym_run_" + std::to_string(::getpid()) + "_" + std::to_string(++serial) + ".stderr");
}

// In the forked child: limits, privileges, folder; exits 126 when one fails.
void apply_limits_in_child(const RunLimits& limits) {
  if (limits.file_size > 0) {
    ::signal(SIGXFSZ, SIG_IGN);
    const rlimit lim{limits.file_size, limits.file_size};
    if (::setrlimit(RLIMIT_FSIZE, &lim) != 0) ::_exit(126);
  }
  // AddressSanitizer reserves terabytes of address space for its shadow
  // memory and cannot start under RLIMIT_AS: for a sanitized binary
  // (scripts/test sets MANDISYM_SANITIZED=1) the limit is left out; the peak
  // RSS check (wait4) still bounds what the run really used.
  if (limits.address_space > 0 && !std::getenv("MANDISYM_SANITIZED")) {
    const rlimit lim{limits.address_space, limits.address_space};
    if (::setrlimit(RLIMIT_AS, &lim) != 0) ::_exit(126);
  }
  if (limits.as_nobody && ::geteuid() == 0) {
    if (::setgroups(0, nullptr) != 0 || ::setgid(65534) != 0 || ::setuid(65534) != 0) ::_exit(126);
  }
  if (!limits.cwd.empty() && ::chdir(limits.cwd.c_str()) != 0) ::_exit(126);
}

// The one JSON line of a case (MANDISYM_CORPUS_LOG).
void append_to_corpus_log(const RunResult& r, int expected_code, const std::string& category) {
  const char* log = std::getenv("MANDISYM_CORPUS_LOG");
  if (!log || !*log) return;
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string line = r.err.substr(0, r.err.find('\n'));
  if (line.size() > 200) line.resize(200);
  Json v = Json::object();
  v["suite"] = Json(info ? std::string(info->test_suite_name()) : std::string());
  v["test"] = Json(info ? std::string(info->name()) : std::string());
  v["category"] = Json(category.empty() ? infer_category(r, expected_code) : category);
  v["expected"] = Json(expected_code);
  v["exit"] = r.exited ? Json(r.code) : Json();
  v["signal"] = Json(r.signal);
  v["guard_killed"] = Json(r.guard_killed);
  v["peak_rss_mb"] = Json(std::round(static_cast<double>(r.peak_rss_kb) / 102.4) / 10.0);
  v["seconds"] = Json(std::round(r.seconds * 100.0) / 100.0);
  v["line"] = Json(line);
  v["command"] = Json(r.command);
  const std::string text = ms::dump_json(v, -1) + "\n";
  // O_APPEND: one write per line, so suites may run at the same time.
  const int fd = ::open(log, O_WRONLY | O_CREAT | O_APPEND, 0644);
  ASSERT_GE(fd, 0) << "cannot open MANDISYM_CORPUS_LOG " << log;
  const ssize_t n = ::write(fd, text.data(), text.size());
  ::close(fd);
  EXPECT_EQ(n, static_cast<ssize_t>(text.size())) << "cannot write MANDISYM_CORPUS_LOG " << log;
}

// The corpus budget: no hang (guard), peak RSS below 2 GB.
void expect_within_budget(const RunResult& r) {
  EXPECT_FALSE(r.guard_killed) << "hang: " << describe(r);
  EXPECT_LT(r.peak_rss_kb, kCorpusMemoryBudgetKb) << "peak RSS " << r.peak_rss_kb / 1024 << " MB over the corpus budget";
}

}  // namespace

const std::string& binary_under_test() {
  static const std::string bin = [] {
    const char* env = std::getenv("MANDISYM_BINARY_UNDER_TEST");
    return std::string(env && *env ? env : MANDISYM_BINARY);
  }();
  return bin;
}

// ---------------------------------------------------------------- TempCase

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

void remove_tree(const fs::path& p) {
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(p, ec))) return;
  if (fs::is_directory(fs::symlink_status(p, ec))) {
    ::chmod(p.c_str(), 0755);  // a chmod 000 folder is opened first
    for (auto it = fs::recursive_directory_iterator(p, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
      if (!it->is_symlink(ec)) ::chmod(it->path().c_str(), 0755);
  }
  fs::remove_all(p, ec);
  if (fs::exists(fs::symlink_status(p, ec))) {  // a locked folder deeper down: one more pass
    for (auto it = fs::recursive_directory_iterator(p, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
      if (!it->is_symlink(ec)) ::chmod(it->path().c_str(), 0755);
    fs::remove_all(p, ec);
  }
}

TempCase::TempCase(const std::string& prefix) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info ? std::string(info->test_suite_name()) + "_" + info->name() : "case";
  std::replace(name.begin(), name.end(), '/', '_');  // parameterised: Prefix/Suite.Test/Case
  root_ = fs::temp_directory_path() / (prefix + "_" + name + "_" + std::to_string(::getpid()));
  remove_tree(root_);
  fs::create_directories(root_);
}

TempCase::~TempCase() {
  if (!std::getenv("MANDISYM_KEEP_BAD_INPUT")) remove_tree(root_);
}

// ---------------------------------------------------------------- running

Child start_binary(const std::vector<std::string>& args, const fs::path& scratch, const RunLimits& limits) {
  Child c;
  const std::string& bin = binary_under_test();
  c.result.args = args;
  c.result.command = bin;
  for (const auto& a : args) c.result.command += " " + a;
  c.stderr_file = stderr_file_for(scratch);
  // The guard finds hangs, it is no timing assertion: a sanitized build runs
  // 2-3x slower (ASan/UBSan instrumentation), so it gets 3x the time.
  c.guard_seconds = limits.guard_seconds * (std::getenv("MANDISYM_SANITIZED") ? kSanitizedSlowdown : 1);
  c.started = now_seconds();
  c.pid = ::fork();
  if (c.pid == 0) {
    ::setpgid(0, 0);  // its own process group: the guard kills all of it
    const int out = ::open("/dev/null", O_WRONLY);
    const int err = ::open(c.stderr_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (out >= 0) ::dup2(out, 1);
    if (err >= 0) ::dup2(err, 2);
    apply_limits_in_child(limits);
    std::vector<char*> argv{const_cast<char*>(bin.c_str())};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(bin.c_str(), argv.data());
    ::_exit(127);
  }
  if (c.pid > 0) ::setpgid(c.pid, c.pid);  // also here: no race with the guard
  return c;
}

RunResult wait_binary(Child& c) {
  RunResult r = c.result;
  if (c.pid <= 0) {
    r.err = "fork failed";
    return r;
  }
  int st = 0;
  rusage ru{};
  while (::wait4(c.pid, &st, WNOHANG, &ru) == 0) {
    if (c.guard_seconds > 0 && now_seconds() - c.started > c.guard_seconds) {
      ::kill(-c.pid, SIGKILL);
      ::wait4(c.pid, &st, 0, &ru);
      r.guard_killed = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  r.seconds = now_seconds() - c.started;
  r.exited = WIFEXITED(st);
  r.code = r.exited ? WEXITSTATUS(st) : -1;
  r.signal = WIFSIGNALED(st) ? WTERMSIG(st) : 0;
  r.peak_rss_kb = ru.ru_maxrss;
  r.err = slurp(c.stderr_file);
  std::error_code ec;
  fs::remove(c.stderr_file, ec);
  c.pid = -1;
  return r;
}

RunResult run_binary(const std::vector<std::string>& args, const fs::path& scratch, const RunLimits& limits) {
  // Under AddressSanitizer there is no RLIMIT_AS (apply_limits_in_child); a
  // `run` then gets the budget the limit would have given it by default
  // (ms::kMemoryBudgetFraction = 0.75 of RLIMIT_AS) as --max-memory.
  std::vector<std::string> a = args;
  if (limits.address_space > 0 && std::getenv("MANDISYM_SANITIZED") && !a.empty() && a[0] == "run") {
    a.push_back("--max-memory");
    a.push_back(std::to_string(static_cast<unsigned long long>(limits.address_space) / 4 * 3));
  }
  Child c = start_binary(a, scratch, limits);
  return wait_binary(c);
}

bool could_not_run_unprivileged(const RunResult& r) {
  return r.exited && (r.code == 126 || r.code == 127) && r.err.empty();
}

std::string describe(const RunResult& r) {
  if (r.guard_killed) return "still running after " + std::to_string(static_cast<int>(r.seconds)) + " s (killed)";
  if (!r.exited) return "killed by signal " + std::to_string(r.signal) + ", stderr: " + r.err;
  return "exit " + std::to_string(r.code) + ", stderr: " + r.err;
}

// ---------------------------------------------------------------- the contract

std::string infer_category(const RunResult& r, int expected_code) {
  const std::string sub = r.args.empty() ? "" : r.args[0];
  if (sub == "compare" || sub == "batch") return sub;
  if (expected_code == 2) return "options";
  if (expected_code == 7) return "output";
  const fs::path in = r.args.size() > 1 ? fs::path(r.args[1]) : fs::path();
  std::string name = in.filename().string();
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  auto ends = [&](const std::string& s) { return name.size() >= s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0; };
  if (ends(".nii") || ends(".nii.gz")) return "nifti";
  if (ends(".nrrd") || ends(".nhdr")) return "nrrd";
  if (ends(".mha") || ends(".mhd")) return "mha";
  std::error_code ec;
  if (ends(".dcm") || fs::is_directory(in, ec) || in.extension().empty()) return "dicom";
  return "volume";
}

void record_case(const RunResult& r, int expected_code, const std::string& category) {
  append_to_corpus_log(r, expected_code, category);
  SCOPED_TRACE(r.command);
  expect_within_budget(r);
}

void expect_refused(const RunResult& r, int expected_code, const fs::path& out, const std::vector<std::string>& names,
                    const std::string& category) {
  append_to_corpus_log(r, expected_code, category);
  SCOPED_TRACE(r.command);
  expect_within_budget(r);
  ASSERT_TRUE(r.exited) << describe(r);
  EXPECT_NE(r.code, 1) << "internal error; stderr:\n" << r.err;
  EXPECT_EQ(r.code, expected_code) << "stderr:\n" << r.err;
  // Exactly one line.
  EXPECT_FALSE(r.err.empty());
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "stderr is not one line:\n" << r.err;
  EXPECT_TRUE(!r.err.empty() && r.err.back() == '\n') << r.err;
  EXPECT_EQ(r.err.rfind(kPrefix, 0), 0u) << "stderr does not start with '" << kPrefix << "':\n" << r.err;
  for (const auto& n : names) EXPECT_NE(r.err.find(n), std::string::npos) << "stderr does not name '" << n << "':\n" << r.err;
  EXPECT_FALSE(fs::exists(out / "results.json")) << "results.json written for refused input";
  EXPECT_FALSE(fs::exists(out / "report.html")) << "report.html written for refused input";
}

}  // namespace ms::testing
