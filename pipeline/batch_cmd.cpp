// `mandisym batch DIR_OR_CSV -o OUT [--jobs N]`: one `run` per study, in
// child processes (a crash or an error in one study never stops the others),
// resumable, with cohort.csv and cohort.html.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/mman.h>
#include <sys/syscall.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

#include "core/error.h"
#include "core/files.h"
#include "core/json_text.h"
#include "core/memory.h"
#include "pipeline/batch_support.h"
#include "pipeline/cohort_files.h"
#include "pipeline/commands.h"
#include "reports/writers.h"
#include "threads/threads.h"

extern char** environ;
namespace fs = std::filesystem;

namespace ms::pipeline {

const cli::CommandSpec& batch_spec() {
  static const cli::CommandSpec s{
      "batch",
      "Run every study of a folder or a CSV list; write cohort.csv and cohort.html.",
      "SOURCE is a folder whose sub-folders and volume files are the studies (study id = their name), or a CSV file "
      "with a header and columns id,path (path relative to the CSV's folder or absolute) and, optionally, per-study "
      "run options that override those after `--`: mask (relative like path), label, hu_offset, orientation, series. "
      "Each study runs as a separate `mandisym run` process into OUT/<id>/ (ids are sanitised into safe folder names), "
      "up to --jobs at a time, each held to --threads-per-job threads and an equal share of the memory budget. Studies "
      "whose OUT/<id>/results.json already exists and parses are skipped (resumable; `run` writes results.json last, so "
      "an interrupted study never looks complete); failed ones are run again. A failed study is recorded with its exit "
      "code and error line (a study killed by a signal as `killed`, one over --study-timeout as `timeout`), and the others "
      "go on. Ctrl-C stops launching, interrupts the running studies, and still writes the cohort files. Exit code 0 when "
      "every study succeeded, 9 when some failed (see cohort.csv), 130 when interrupted.",
      {{"SOURCE", "folder of studies, or CSV with id,path"}},
      {{"output", "DIR", "output folder (created)", ""},
       {"jobs", "N|auto", "studies run at once; auto = as many as the cores allow while 2 x the largest peak memory "
                          "measured so far fits the memory budget per study (the first study runs alone)", "1"},
       {"threads-per-job", "T", "threads of each study's run (--threads of `run`)", "the cores / --jobs, at least 1", 1, 1024},
       {"deidentify", "", "pass --deidentify to every run; study ids become pseudonyms (keyed by OUT/.deidentify-key) and "
                          "error lines and logs are scrubbed of paths, UIDs and dates", ""},
       {"study-timeout", "SECONDS", "kill a study's process group when it has run this long and record it as `timeout`; "
                                    "default 600 s + 1 s per MB of the study's files; 0 = none", ""},
       {"aggregate-only", "", "run nothing: write the cohort files from the studies already in OUT (e.g. after a "
                              "Snakemake or cluster run); incomplete studies are listed as failed with their log's error", ""},
       {"check-only", "", "run nothing, write nothing: check SOURCE and every study's run options (those after `--` "
                          "and the CSV's columns) as batch does before it starts; exit 0 or 2 (the Snakemake workflow "
                          "calls it before submitting jobs)", ""},
       {"quiet", "", "no progress output", ""},
       {"help", "", "show this help", ""}},
      "options for every study's `mandisym run`, e.g. -- --hu-offset -1000 --orientation LPS; checked before any "
      "study starts and recorded per study in cohort.csv (`options`). -o, --threads and --deidentify belong to batch "
      "(OUT, --threads-per-job, --deidentify)."};
  return s;
}

namespace {

std::atomic<bool> g_interrupted{false};
void on_sigint(int) { g_interrupted = true; }

namespace bs = batch_support;

using cohort::Study;
using cohort::split_csv_line;

// CSV columns that give a study its own run option: column -> option. Paths
// (mask) are relative to the CSV's folder, as `path` is.
const std::pair<const char*, const char*> kStudyOptionColumns[] = {
    {"mask", "--mask"}, {"label", "--label"}, {"hu_offset", "--hu-offset"}, {"orientation", "--orientation"}, {"series", "--series"}};

// --jobs auto: studies run at once only while this many times the largest
// peak resident memory measured so far, per study, fits the memory budget
// (core/memory.h). 2: the peak of a run grows with the scan (4.3 floats per
// voxel, docs/ingest.md), and the next study may be up to twice as large as
// the largest so far before the sum overruns the budget.
constexpr double kAutoJobsPeakMargin = 2.0;

// The options every study's run gets from batch itself; refused after `--`.
const char* const kBatchOwnedRunOptions[] = {"output", "threads", "deidentify", "help"};

std::string safe_id(std::string s) {
  for (char& c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.')) c = '_';
  if (s.empty() || s[0] == '.') s = "_" + s;
  return s;
}


std::vector<Study> list_studies(const std::string& source) {
  std::vector<Study> out;
  const fs::path src = source;
  if (fs::is_directory(src)) {
    std::vector<fs::path> entries;
    for (const auto& e : fs::directory_iterator(src))
      if (e.path().filename().string()[0] != '.') entries.push_back(e.path());
    std::sort(entries.begin(), entries.end());
    for (const auto& p : entries) {
      Study st;
      st.name = p.filename().string();
      st.id = safe_id(st.name);
      st.path = p.string();
      out.push_back(st);
    }
  } else if (fs::is_regular_file(src)) {
    std::ifstream f(src);
    std::string line;
    if (!std::getline(f, line)) throw Error(ExitCode::InputInvalid, source + ": empty CSV");
    const auto head = split_csv_line(line);
    const auto col = [&](const char* name) {
      for (std::size_t i = 0; i < head.size(); ++i)
        if (head[i] == name) return static_cast<long>(i);
      return -1L;
    };
    const long ci = col("id"), cp = col("path");
    if (cp < 0) throw Error(ExitCode::InputInvalid, source + ": the CSV needs a header with columns id,path");
    int row = 1;
    while (std::getline(f, line)) {
      ++row;
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      const auto v = split_csv_line(line);
      if (static_cast<long>(v.size()) <= cp) throw Error(ExitCode::InputInvalid, source + ": line " + std::to_string(row) + " has no path");
      fs::path p = v[static_cast<std::size_t>(cp)];
      if (p.is_relative()) p = src.parent_path() / p;
      const std::string id = ci >= 0 && static_cast<long>(v.size()) > ci && !v[static_cast<std::size_t>(ci)].empty()
                                 ? v[static_cast<std::size_t>(ci)]
                                 : p.filename().string();
      Study st;
      st.name = id;
      st.id = safe_id(id);
      st.path = p.string();
      if (const long cg = col("group"); cg >= 0 && static_cast<long>(v.size()) > cg) st.group = v[static_cast<std::size_t>(cg)];
      for (const auto& [column, option] : kStudyOptionColumns) {
        const long c = col(column);
        if (c < 0 || static_cast<long>(v.size()) <= c || v[static_cast<std::size_t>(c)].empty()) continue;
        std::string value = v[static_cast<std::size_t>(c)];
        if (std::string(column) == "mask" && fs::path(value).is_relative()) value = (src.parent_path() / value).string();
        st.options.insert(st.options.end(), {option, value});
      }
      out.push_back(st);
    }
  } else {
    throw Error(ExitCode::InputNotFound, source + ": no such folder or CSV file");
  }
  if (out.empty()) throw Error(ExitCode::InputInvalid, source + ": no studies found");
  return out;
}

// `run`'s arguments for a study: batch's `--` options, then the study's own;
// parsed and checked as `run` checks them (the input and OUT are stand-ins).
cli::Args study_run_args(const std::vector<std::string>& common, const std::vector<std::string>& own) {
  std::vector<std::string> argv = {"INPUT", "-o", "OUT"};
  argv.insert(argv.end(), common.begin(), common.end());
  argv.insert(argv.end(), own.begin(), own.end());
  const cli::Args a = cli::parse(run_spec(), argv);
  check_run_options(a);
  return a;
}

// Refuses, before any study starts, run options that `run` would refuse or
// that batch sets itself: batch's `--` options, then each study's own.
void check_run_options_of(const std::vector<Study>& studies, const std::vector<std::string>& common) {
  try {
    const cli::Args a = study_run_args(common, {});
    for (const char* owned : kBatchOwnedRunOptions)
      if (a.has(owned) && std::string(owned) != "output")
        throw Error(ExitCode::Usage, std::string("--") + owned + " is set by batch itself (see mandisym batch --help)");
    for (const auto& w : common)
      if (w == "-o" || w == "--output" || w.rfind("--output=", 0) == 0)
        throw Error(ExitCode::Usage, "-o is set by batch itself (OUT/<id>)");
  } catch (const Error& e) {
    throw Error(ExitCode::Usage, std::string("batch: run options after --: ") + e.what());
  }
  for (const Study& s : studies) {
    if (s.options.empty()) continue;
    try {
      study_run_args(common, s.options);
    } catch (const Error& e) {
      throw Error(ExitCode::InputInvalid, "batch: study " + s.name + ": its CSV options: " + e.what());
    }
  }
}

// Unique ids: a repeated id gets _2, _3, ...
void make_ids_unique(std::vector<Study>& studies) {
  std::map<std::string, int> seen;
  for (auto& s : studies) {
    const int k = seen[s.id]++;
    if (k) s.id += "_" + std::to_string(k + 1);
  }
}

bool complete(const fs::path& dir) {
  try {
    const Json v = parse_json(read_file_or_empty((dir / "results.json").string()));
    return v.contains("schema_version") && v.contains("scores");
  } catch (const std::exception&) {
    return false;
  }
}

// The options a finished run was given, from the command line its log.txt
// records (line 2: `mandisym run INPUT -o DIR [options]`), without the input,
// the output folder and -q. A de-identified run logs only
// `mandisym run <input> --deidentify ...`.
std::string options_in_log(const fs::path& dir) {
  std::istringstream log(read_file_or_empty((dir / "log.txt").string()));
  std::string line;
  std::getline(log, line);
  std::getline(log, line);
  std::istringstream words(line);
  std::vector<std::string> w;
  for (std::string x; words >> x;) w.push_back(x);
  if (w.size() < 3 || w[0] != "mandisym" || w[1] != "run") return "";
  std::string options;
  for (std::size_t k = 3; k < w.size(); ++k) {
    if (w[k] == "-o" || w[k] == "--output") ++k;
    else if (w[k] != "-q" && w[k] != "--quiet") options += (options.empty() ? "" : " ") + w[k];
  }
  return options;
}

// A complete study's status as its results.json says: `qc_failed` (exit 8,
// every output written; docs/qc.md) when its quality control failed, else
// `done-earlier`; its options as its log records them.
void record_complete(Study& s, const fs::path& dir) {
  s.status = "done-earlier", s.exit_code = 0;
  s.run_options = options_in_log(dir);
  try {
    const Json v = parse_json(read_file_or_empty((dir / "results.json").string()));
    const Json* qc = find_member(v, "qc");
    const Json* status = qc ? find_member(*qc, "status") : nullptr;
    if (status && status->is_string() && status->get<std::string>() == "fail") {
      s.status = "qc_failed", s.exit_code = static_cast<int>(ExitCode::QcFailed), s.error = "quality control failed (see its report)";
      const Json* cause = find_member(*qc, "cause");
      if (cause && cause->is_string()) s.error = "result failed quality control: " + cause->get<std::string>();
    }
  } catch (const std::exception&) {
  }
}

// All a descriptor holds (a study's memfd log), from its start.
std::string read_fd(int fd) {
  std::string out;
  char buf[65536];
  ::lseek(fd, 0, SEEK_SET);
  for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) out.append(buf, static_cast<std::size_t>(n));
  return out;
}

std::string signal_text(int sig) {
  const char* d = ::strsignal(sig);
  return "signal " + std::to_string(sig) + (d ? std::string(" (") + d + ")" : std::string());
}

// One running study.
struct Child {
  std::size_t study;
  int log_fd = -1;  // memfd with its stdout+stderr; written to OUT/.logs/<id>.log (scrubbed) when it ends
  std::chrono::steady_clock::time_point start;
  double timeout_s = 0;  // 0: none
  bool timed_out = false, interrupted = false;
  std::chrono::steady_clock::time_point term_sent;
};

// What every study's run gets: the binary, OUT, and the options batch sets.
struct LaunchPlan {
  std::string exe;
  fs::path out;
  bool deidentify = false;
  std::vector<std::string> common;  // the options after batch's `--`
  int threads = 1;                  // --threads of each run
  std::uint64_t memory_share = 0;   // --max-memory of each run when `--` sets none; 0: run's default
};

// `run`'s command line for study s.
std::vector<std::string> run_command_line(const Study& s, const LaunchPlan& plan) {
  std::vector<std::string> a = {plan.exe, "run", s.path, "-o", (plan.out / s.id).string(), "-q", "--threads", std::to_string(plan.threads)};
  if (plan.memory_share > 0) a.insert(a.end(), {"--max-memory", std::to_string(plan.memory_share)});
  if (plan.deidentify) a.push_back("--deidentify");
  a.insert(a.end(), plan.common.begin(), plan.common.end());
  a.insert(a.end(), s.options.begin(), s.options.end());
  return a;
}

// Starts `mandisym run` for a study in its own process group; its output goes
// to a memfd (nothing that names the study reaches the disk before scrubbing).
bool launch(Study& s, const LaunchPlan& plan, pid_t* pid, int* log_fd) {
  *log_fd = static_cast<int>(::syscall(SYS_memfd_create, "mandisym-study-log", MFD_CLOEXEC));
  if (*log_fd < 0) return false;
  std::vector<std::string> a = run_command_line(s, plan);
  s.run_options.clear();
  for (std::size_t k = 6; k < a.size(); ++k) s.run_options += (k > 6 ? " " : "") + a[k];  // after `run INPUT -o DIR -q`
  if (plan.deidentify) s.run_options = bs::scrub(s.run_options, bs::identifying_strings(s.path, s.name), s.id);
  std::vector<char*> argv;
  for (auto& x : a) argv.push_back(x.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, *log_fd, 1);
  posix_spawn_file_actions_adddup2(&fa, *log_fd, 2);
  posix_spawnattr_t at;
  posix_spawnattr_init(&at);
  posix_spawnattr_setflags(&at, POSIX_SPAWN_SETPGROUP);  // its own group: a timeout kills it and its children
  posix_spawnattr_setpgroup(&at, 0);
  const int rc = posix_spawn(pid, plan.exe.c_str(), &fa, &at, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&at);
  if (rc != 0) ::close(*log_fd), *log_fd = -1;
  return rc == 0;
}

// Records how a child ended (wait status st) and writes its log.
void finish(Study& s, Child& c, int st, const fs::path& out, bool deidentify) {
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - c.start).count();
  std::string log = read_fd(c.log_fd);
  ::close(c.log_fd);
  if (deidentify) log = bs::scrub(log, bs::identifying_strings(s.path, s.name), s.id);
  reports::write_text_atomic((out / ".logs" / (s.id + ".log")).string(), log);
  s.exit_code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  s.signal = WIFSIGNALED(st) ? WTERMSIG(st) : 0;
  const std::string line = bs::first_error_line(log);
  if (c.timed_out) {
    s.status = "timeout";
    char b[160];
    std::snprintf(b, sizeof b, "no result within --study-timeout %.0f s; its process group was killed", c.timeout_s);
    s.error = b;
  } else if (s.exit_code == 0 && complete(out / s.id)) {
    s.status = "ok";
  } else if (s.exit_code == static_cast<int>(ExitCode::QcFailed) && complete(out / s.id)) {
    s.status = "qc_failed";  // every output written; the checks that failed are in its results.json (docs/qc.md)
    s.error = line;
  } else if (c.interrupted || (g_interrupted && WIFSIGNALED(st))) {
    s.status = "not run (interrupted)";
  } else if (WIFSIGNALED(st)) {
    s.status = "killed";
    s.error = "killed by " + signal_text(s.signal) + (line.empty() ? "" : ": " + line);
  } else {
    s.status = "failed";
    s.error = line.empty() ? "exit code " + std::to_string(s.exit_code) : line;
  }
}

// Signals every child's process group: SIGTERM (or SIGINT on Ctrl-C) when a
// timeout expires, SIGKILL kKillGraceS later.
void police(std::map<pid_t, Child>& running) {
  const auto now = std::chrono::steady_clock::now();
  for (auto& [pid, c] : running) {
    const double el = std::chrono::duration<double>(now - c.start).count();
    if (!c.timed_out && !c.interrupted && c.timeout_s > 0 && el > c.timeout_s) {
      c.timed_out = true, c.term_sent = now;
      ::kill(-pid, SIGTERM);
    } else if (!c.timed_out && !c.interrupted && g_interrupted) {
      c.interrupted = true, c.term_sent = now;
      ::kill(-pid, SIGINT);
    } else if ((c.timed_out || c.interrupted) && std::chrono::duration<double>(now - c.term_sent).count() > bs::kKillGraceS) {
      ::kill(-pid, SIGKILL);
    }
  }
}

// Aggregate-only: a study that has no complete run. Its exit code comes from
// OUT/.done/<id> ("EXIT SECONDS", written by workflow/Snakefile; `timeout`
// gives 124 on expiry, 128+N for a signal) when there is one.
void record_unfinished(Study& s, const fs::path& out) {
  s.status = "failed";
  const std::string log = read_file_or_empty((out / ".logs" / (s.id + ".log")).string());
  s.error = bs::first_error_line(log);
  std::ifstream f(out / ".done" / s.id);
  int rc = -1;
  double secs = -1;
  if (f >> rc) {
    if (f >> secs) s.seconds = secs;
    if (rc == 124) {
      s.status = "timeout", s.error = "no result within the workflow's study_timeout; killed";
    } else if (rc > 128 && rc < 128 + 65) {
      s.status = "killed", s.signal = rc - 128;
      s.error = "killed by " + signal_text(s.signal) + (s.error.empty() ? "" : ": " + s.error);
    } else {
      s.exit_code = rc;
    }
  }
  if (s.error.empty()) s.error = "no complete run in " + (out / s.id).string();
}



// How many studies run at once and with how many threads each (docs/batch.md,
// "Jobs and threads"). A fixed --jobs N: N at once, each with
// --threads-per-job or cores / N threads. --jobs auto: the first study runs
// alone with every core; after that, as many as the cores allow while
// kAutoJobsPeakMargin x the largest peak resident memory measured so far, per
// study, fits the memory budget.
struct JobPolicy {
  bool automatic = false;
  int fixed_jobs = 1;
  int fixed_threads = 0;  // 0: cores / jobs
  int cores = 1;
  std::uint64_t budget_bytes = 0;  // default_memory_budget_bytes(); 0: unknown
  long largest_peak_kb = -1;       // over the studies finished so far

  int jobs() const {
    if (!automatic) return fixed_jobs;
    if (largest_peak_kb <= 0) return 1;
    if (budget_bytes == 0) return cores;
    const double per_job = kAutoJobsPeakMargin * static_cast<double>(largest_peak_kb) * 1024.0;
    return std::clamp(static_cast<int>(static_cast<double>(budget_bytes) / per_job), 1, cores);
  }
  int threads() const { return fixed_threads > 0 ? fixed_threads : std::max(1, cores / jobs()); }
};

JobPolicy job_policy(const cli::Args& args) {
  JobPolicy p;
  p.cores = threads::available_cores();
  p.budget_bytes = default_memory_budget_bytes();
  p.automatic = args.get("jobs", "1") == "auto";
  if (!p.automatic) {
    const double jobs = args.number_in("jobs", 1, 1, 256, "");
    if (jobs != std::floor(jobs)) throw Error(ExitCode::Usage, "--jobs: expected a whole number or auto");
    p.fixed_jobs = static_cast<int>(jobs);
  }
  if (args.has("threads-per-job")) p.fixed_threads = static_cast<int>(args.ranged("threads-per-job", 1, ""));
  return p;
}

// One progress line ("[###...] 3/10 studies, 2 running, ...").
void print_progress(std::size_t done, std::size_t todo, std::size_t running, double elapsed_s, bool tty) {
  const double eta = done ? elapsed_s / static_cast<double>(done) * static_cast<double>(todo - done) : 0;
  char b[160];
  const int width = 30, fill = todo ? static_cast<int>(width * done / todo) : width;
  std::snprintf(b, sizeof b, "[%s%s] %zu/%zu studies, %zu running, elapsed %.0f s, ETA %.0f s", std::string(fill, '#').c_str(),
                std::string(width - fill, '.').c_str(), done, todo, running, elapsed_s, eta);
  if (tty) std::cout << "\r" << b << std::flush;
  else std::cout << b << "\n";
}

// Runs the studies not done yet, as many at a time as the job policy says,
// each under its timeout (--study-timeout; default from its size,
// batch_support.h).
void run_studies(std::vector<Study>& studies, const cli::Args& args, LaunchPlan plan, std::size_t todo) {
  JobPolicy policy = job_policy(args);
  const bool quiet = args.has("quiet");
  const bool own_memory_option = !plan.common.empty() && study_run_args(plan.common, {}).has("max-memory");
  const double fixed_timeout = args.number("study-timeout", -1);
  const bool tty = !quiet && isatty(STDOUT_FILENO);
  const auto t0 = std::chrono::steady_clock::now();
  std::size_t next = 0, done = 0;
  std::map<pid_t, Child> running;
  const auto progress = [&] {
    if (!quiet) print_progress(done, todo, running.size(), std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), tty);
  };
  progress();
  while (true) {
    while (!g_interrupted && static_cast<int>(running.size()) < policy.jobs() && next < studies.size()) {
      Study& s = studies[next++];
      if (s.status != "pending") continue;  // complete before this run (done-earlier or qc_failed)
      plan.threads = policy.threads();
      plan.memory_share = own_memory_option || policy.budget_bytes == 0 ? 0 : policy.budget_bytes / static_cast<std::uint64_t>(policy.jobs());
      pid_t pid = -1;
      int fd = -1;
      if (!launch(s, plan, &pid, &fd)) {
        s.status = "failed", s.error = "cannot start " + plan.exe, ++done;
        continue;
      }
      Child c;
      c.study = static_cast<std::size_t>(&s - studies.data());
      c.log_fd = fd;
      c.start = std::chrono::steady_clock::now();
      c.timeout_s = fixed_timeout >= 0 ? fixed_timeout : bs::default_timeout_s(bs::study_bytes(s.path));
      running[pid] = c;
    }
    if (running.empty()) break;
    int st = 0;
    rusage ru{};
    const pid_t pid = ::wait4(-1, &st, WNOHANG, &ru);
    if (pid == 0 || (pid < 0 && errno == EINTR)) {
      police(running);
      ::usleep(50 * 1000);  // 50 ms: the timeout's resolution
      continue;
    }
    if (pid < 0) break;
    auto it = running.find(pid);
    if (it == running.end()) continue;
    if (it->second.timed_out || it->second.interrupted) ::kill(-pid, SIGKILL);  // what it left in its group
    Study& s = studies[it->second.study];
    finish(s, it->second, st, plan.out, plan.deidentify);
    s.peak_kb = ru.ru_maxrss;
    policy.largest_peak_kb = std::max(policy.largest_peak_kb, s.peak_kb);
    running.erase(it);
    ++done;
    progress();
  }
  if (tty) std::cout << "\n";
}

}  // namespace

int batch_command(const cli::Args& args) {
  const std::string out_s = args.get("output");
  if (out_s.empty()) throw Error(ExitCode::Usage, "batch: -o OUT is required");
  (void)job_policy(args);  // --jobs and --threads-per-job checked before anything starts
  if (args.number("study-timeout", 0) < 0) throw Error(ExitCode::Usage, "batch: --study-timeout must be >= 0 seconds (0 = none)");
  const bool quiet = args.has("quiet");
  const fs::path out = out_s;
  std::vector<Study> studies = list_studies(args.positional.at(0));
  check_run_options_of(studies, args.passthrough);
  if (args.has("check-only")) return 0;
  std::error_code ec;
  fs::create_directories(out / ".logs", ec);
  if (ec) throw Error(ExitCode::OutputFailed, out.string() + ": cannot create the output folder: " + ec.message());
  if (args.has("deidentify")) {  // pseudonymous ids: folder names often carry the patient's name
    const std::string key = bs::deidentify_key(out);
    for (auto& s : studies) s.id = bs::pseudonym(key, s.name);
  }
  make_ids_unique(studies);

  struct sigaction sa {};
  sa.sa_handler = on_sigint;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);

  std::size_t todo = 0;
  const bool aggregate_only = args.has("aggregate-only");
  for (auto& s : studies)
    if (complete(out / s.id)) record_complete(s, out / s.id);
    else if (aggregate_only) record_unfinished(s, out);
    else ++todo;
  if (!aggregate_only) {
    LaunchPlan plan;
    plan.exe = bs::self_exe();
    plan.out = out;
    plan.deidentify = args.has("deidentify");
    plan.common = args.passthrough;
    run_studies(studies, args, plan, todo);
  }
  for (auto& s : studies)
    if (s.status == "pending") s.status = "not run (interrupted)";

  const cohort::Table table = cohort::read_results(studies, out);
  cohort::write_cohort_csv(studies, table, out);
  cohort::write_cohort_html(studies, table, cohort::write_cohort_groups(studies, table, out), out, g_interrupted);
  std::size_t n_ok = 0, n_failed = 0;
  for (const auto& s : studies) (s.status == "ok" || s.status == "done-earlier" ? n_ok : n_failed)++;
  if (!quiet) std::cout << "batch: " << n_ok << " complete, " << n_failed << " failed or not run; " << (out / "cohort.html").string() << std::endl;
  if (g_interrupted) return 130;
  return n_failed ? static_cast<int>(ExitCode::BatchIncomplete) : 0;
}

}  // namespace ms::pipeline
