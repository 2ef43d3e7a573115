// Test support: runs the real mandisym binary (fork/exec, no shell) for the
// end-to-end hostile-input suites (tests/e2e/test_bad_input.cpp,
// test_hostile_ingest.cpp, test_hostile_batch_compare.cpp) and checks the
// refusal contract (README.md, "Exit codes"):
//   1. the documented non-zero exit code (2 usage, 3 input not found or
//      unreadable, 4 invalid input, 5 no mandible, 6 geometry, 7 output);
//   2. stderr is exactly one line, starting "mandisym: error: ", naming the
//      offending path (and the key words a test asks for);
//   3. no crash: death by a signal or exit code 1 (internal error) fails;
//   4. OUTDIR holds no results.json and no report.html afterwards;
// plus the hostile-input corpus budget (issue "O. Hostile input": every case
// within 2 GB and 60 s): the guard did not have to kill the binary (a hang),
// and its peak RSS stayed below kCorpusMemoryBudgetKb.
//
// MANDISYM_BINARY_UNDER_TEST=/path/to/mandisym runs the suites against another
// build; MANDISYM_KEEP_BAD_INPUT=1 keeps the per-test folders;
// MANDISYM_CORPUS_LOG=FILE appends one JSON line per case to FILE (read by
// scripts/hostile-corpus).
#pragma once

#include <sys/resource.h>
#include <sys/types.h>

#include <filesystem>
#include <string>
#include <vector>

namespace ms::testing {

// The corpus budget (issue "O. Hostile input": 2 GB and 60 s per case).
constexpr long kCorpusMemoryBudgetKb = 2L * 1024 * 1024;
constexpr int kCorpusSeconds = 60;
// How much longer the hang guard waits under MANDISYM_SANITIZED=1.
constexpr int kSanitizedSlowdown = 3;

// MANDISYM_BINARY_UNDER_TEST when set, else the build's mandisym.
const std::string& binary_under_test();

// A fresh folder per test (<prefix>_<suite>_<test>_<pid> under the temp
// folder), removed afterwards even when a test made parts of it unreadable.
class TempCase {
 public:
  explicit TempCase(const std::string& prefix = "mandisym");
  ~TempCase();
  TempCase(const TempCase&) = delete;
  TempCase& operator=(const TempCase&) = delete;
  const std::filesystem::path& root() const { return root_; }
  std::filesystem::path operator/(const std::string& s) const { return root_ / s; }
  std::filesystem::path out() const { return root_ / "out"; }

 private:
  std::filesystem::path root_;
};

// chmod-safe recursive removal (chmod 000 folders and files included).
void remove_tree(const std::filesystem::path& p);

// A file's bytes ("" when it cannot be read).
std::string slurp(const std::filesystem::path& p);

struct RunResult {
  bool exited = false;       // normal exit (not a signal)
  int code = -1;             // exit code when exited
  int signal = 0;            // signal when not exited
  std::string err;           // stderr
  std::string command;       // for messages
  std::vector<std::string> args;
  long peak_rss_kb = 0;      // wait4 ru_maxrss: the binary or any child it waited for
  double seconds = 0;        // wall clock
  bool guard_killed = false; // still running after guard_seconds: killed (a hang)
};

struct RunLimits {
  // When the tests run as root, the binary runs as uid/gid 65534 so that file
  // permissions apply (exit 126 with empty stderr when that is impossible).
  bool as_nobody = false;
  // RLIMIT_FSIZE in bytes (a full disk as the writer sees it: EFBIG; SIGXFSZ
  // is ignored, as a shell's `trap "" XFSZ` would); 0 = none.
  rlim_t file_size = 0;
  // RLIMIT_AS in bytes; 0 = none.
  rlim_t address_space = 0;
  // Hang guard, not a timing assertion: after this the child's process group
  // gets SIGKILL and the result is marked guard_killed.
  int guard_seconds = kCorpusSeconds;
  // Working folder of the child; empty = the test's.
  std::filesystem::path cwd;
};

// A started binary (see start_binary / wait_binary).
struct Child {
  pid_t pid = -1;
  std::filesystem::path stderr_file;
  RunResult result;  // command and args filled in
  int guard_seconds = kCorpusSeconds;
  double started = 0;
};

// Starts `mandisym ARGS...` in its own process group, stdout to /dev/null,
// stderr to SCRATCH.stderr next to scratch (which need not exist; in the temp
// folder when scratch's folder is not a folder), removed after the run.
Child start_binary(const std::vector<std::string>& args, const std::filesystem::path& scratch, const RunLimits& limits = {});
// Waits for it (killing its process group after guard_seconds).
RunResult wait_binary(Child& child);
// start_binary + wait_binary.
RunResult run_binary(const std::vector<std::string>& args, const std::filesystem::path& scratch, const RunLimits& limits = {});

// True when an as_nobody run could not drop privileges (the test should skip).
bool could_not_run_unprivileged(const RunResult& r);

// "still running after N s (killed)" or "exit N, stderr: ...".
std::string describe(const RunResult& r);

// The contract above plus the budget; records the case (see record_case).
// category: dicom|nifti|nrrd|mha|volume|batch|compare|output|options; empty =
// inferred from the command (see infer_category).
void expect_refused(const RunResult& r, int expected_code, const std::filesystem::path& out,
                    const std::vector<std::string>& names, const std::string& category = "");

// For a case checked otherwise (a batch that exits 9, a compare that warns):
// checks the budget only and appends the case to MANDISYM_CORPUS_LOG.
void record_case(const RunResult& r, int expected_code, const std::string& category = "");

// compare / batch by subcommand; 2 options; 7 output; else by the input's
// extension (.nii[.gz] nifti, .nrrd/.nhdr nrrd, .mha/.mhd mha, .dcm or a
// folder dicom, anything else volume).
std::string infer_category(const RunResult& r, int expected_code);

}  // namespace ms::testing
