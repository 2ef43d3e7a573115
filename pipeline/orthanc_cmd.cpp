// `mandisym orthanc`: a PACS node. Follows an Orthanc server's /changes,
// runs `mandisym run --dicom` on every stable CT series and stores the SEG,
// SR and report back into the same study (docs/pacs.md).
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <thread>

#include "core/error.h"
#include "core/files.h"
#include "core/json_text.h"
#include "pipeline/batch_support.h"
#include "pipeline/commands.h"
#include "pipeline/orthanc_client.h"
#include "reports/writers.h"

namespace fs = std::filesystem;

namespace ms::pipeline {

namespace {
// Seconds between polls of /changes: a series is stored back within this of
// becoming stable (Orthanc's StableAge, 60 s by default, dominates).
constexpr double kDefaultPollS = 2;
// Seconds a series' run may take: 60x the slowest documented run (512 x 512 x
// 450 at 0.5 mm, ~15 s; docs/benchmarks.md), as batch's floor of 600 s plus
// downloads of large series over a LAN.
constexpr double kDefaultStudyTimeoutS = 900;
std::string seconds(double s) { return std::to_string(static_cast<int>(s)); }
}  // namespace

const cli::CommandSpec& orthanc_spec() {
  static const cli::CommandSpec s{
      "orthanc",
      "Run on every stable CT series of an Orthanc server; store the results back.",
      "Follows the server's change log (/changes): each StableSeries of modality CT is downloaded, measured with "
      "`mandisym run --dicom`, and its DICOM SEG, SR and report are stored into the same study (POST /instances). "
      "Series of any other modality, such as MandiSym's own outputs, are never processed. Each series gets a record: "
      "the series metadata 'MandiSym' (declare it in Orthanc's UserMetadata; docs/pacs.md) and a line in WORKDIR/orthanc.log. "
      "The position in the change log is kept in WORKDIR/state.json, so a restart goes on where it stopped. "
      "SIGINT/SIGTERM: the series in progress is finished, then the command exits.",
      {},
      {{"url", "URL", "Orthanc's REST address, e.g. http://127.0.0.1:8042", ""},
       {"credentials", "FILE", "file holding user:password for HTTP basic authentication (not on the command line)", "none"},
       {"work", "WORKDIR", "folder for the state, the log, downloads and each series' outputs (results/<series>/)", ""},
       {"once", "", "process the changes recorded so far, wait for series not yet stable, then exit", ""},
       {"poll", "S", "seconds between polls of /changes", seconds(kDefaultPollS), 0.1, 3600},
       {"study-timeout", "S", "seconds a series' run may take before it is killed", seconds(kDefaultStudyTimeoutS), 10, 86400},
       {"help", "", "show this help", ""}},
      "options passed to every `mandisym run` (e.g. --deidentify, --no-cranial)"};
  return s;
}

namespace {

std::atomic<bool> g_stop{false};
void on_stop(int) { g_stop = true; }

struct Service {
  const OrthancClient& pacs;
  fs::path work;
  std::vector<std::string> run_options;
  double timeout_s = kDefaultStudyTimeoutS;
};

std::string now_text() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  localtime_r(&t, &tm);
  char b[32];
  std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%S", &tm);
  return b;
}

void log_line(const Service& s, const std::string& line) {
  const std::string text = now_text() + " " + line + "\n";
  std::cout << text << std::flush;
  std::FILE* f = std::fopen((s.work / "orthanc.log").c_str(), "a");
  if (f) std::fputs(text.c_str(), f), std::fclose(f);
}

long long load_last_seq(const fs::path& work) {
  const std::string text = read_file_or_empty((work / "state.json").string());
  if (text.empty()) return 0;
  const Json j = parse_json(text);
  const Json* seq = find_member(j, "last_change");
  return seq && seq->is_number_integer() ? seq->get<long long>() : 0;
}

void save_last_seq(const Service& s, long long seq) {
  Json j;
  j["last_change"] = seq;
  j["url"] = s.pacs.url();
  reports::write_text_atomic((s.work / "state.json").string(), dump_json(j, 1) + "\n");
}

// `mandisym run IN -o OUT --dicom -q [options]` in its own process group,
// killed after the timeout; returns its exit code (124 on timeout, 128 + N
// for a signal, as timeout(1) reports them).
int run_study(const Service& s, const fs::path& in, const fs::path& out, const fs::path& log) {
  std::vector<std::string> a = {batch_support::self_exe(), "run", in.string(), "-o", out.string(), "--dicom", "-q"};
  a.insert(a.end(), s.run_options.begin(), s.run_options.end());
  std::vector<char*> argv;
  for (auto& x : a) argv.push_back(x.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  posix_spawnattr_t at;
  posix_spawnattr_init(&at);
  posix_spawnattr_setflags(&at, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&at, 0);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, a[0].c_str(), &fa, &at, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&at);
  if (rc != 0) throw Error(ExitCode::Internal, "cannot start " + a[0] + ": " + std::strerror(rc));
  const auto start = std::chrono::steady_clock::now();
  int st = 0;
  bool timed_out = false;
  while (::waitpid(pid, &st, WNOHANG) == 0) {
    if (!timed_out && std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > s.timeout_s) {
      timed_out = true;
      ::kill(-pid, SIGKILL);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  if (timed_out) return 124;
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

// The series' instances, downloaded into dir; returns how many.
std::size_t download_series(const Service& s, const std::string& series, const fs::path& dir) {
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Json instances = s.pacs.get_json("/series/" + series + "/instances");
  std::size_t n = 0;
  for (const Json& inst : instances) {
    const std::string id = inst.at("ID").get<std::string>();
    s.pacs.download("/instances/" + id + "/file", (dir / (id + ".dcm")).string());
    ++n;
  }
  return n;
}

// POSTs the run's dicom/ objects; each must land in the CT's study.
std::string store_outputs(const Service& s, const fs::path& out, const std::string& study) {
  std::string ids;
  for (const char* name : {"seg", "sr", "report"}) {
    const fs::path f = out / "dicom" / (std::string(name) + ".dcm");
    const Json r = s.pacs.post_file("/instances", f.string());
    const Json* parent = find_member(r, "ParentStudy");
    if (!parent || parent->get<std::string>() != study)
      throw Error(ExitCode::InputInvalid, f.string() + " was stored outside the CT's study (Orthanc answered " + dump_json(r) + ")");
    ids += std::string(" ") + name + "=" + r.at("ID").get<std::string>();
  }
  return ids;
}

// The series' record: Orthanc metadata 'MandiSym' (when the server declares
// it) and the log line.
void record(const Service& s, const std::string& series, const std::string& text) {
  log_line(s, "series " + series + ": " + text);
  try {
    s.pacs.put_text("/series/" + series + "/metadata/MandiSym", text);
  } catch (const Error& e) {
    log_line(s, "series " + series + ": metadata not recorded (declare UserMetadata MandiSym; docs/pacs.md): " + e.what());
  }
}

// One stable series: skip, or download, run, store and record. Returns false
// when the series failed.
bool process_series(const Service& s, const std::string& series) {
  const Json info = s.pacs.get_json("/series/" + series);
  const Json* tags = find_member(info, "MainDicomTags");
  const Json* modality = tags ? find_member(*tags, "Modality") : nullptr;
  const std::string mod = modality && modality->is_string() ? modality->get<std::string>() : "";
  if (mod != "CT") return log_line(s, "series " + series + ": skipped (modality " + (mod.empty() ? "none" : mod) + ")"), true;
  const std::size_t count = info.at("Instances").size();
  bool found = false;
  const std::string done = s.pacs.get_text("/series/" + series + "/metadata/MandiSym", &found);
  if (found && done.find("instances=" + std::to_string(count) + " ") != std::string::npos)
    return log_line(s, "series " + series + ": already processed (" + done + ")"), true;
  const std::string study = info.at("ParentStudy").get<std::string>();
  const fs::path in = s.work / "incoming" / series, out = s.work / "results" / series;
  const auto start = std::chrono::steady_clock::now();
  download_series(s, series, in);
  fs::create_directories(s.work / "logs");
  const int rc = run_study(s, in, out, s.work / "logs" / (series + ".log"));
  fs::remove_all(in);
  const std::string n = "instances=" + std::to_string(count) + " ";
  const std::string log = read_file_or_empty((s.work / "logs" / (series + ".log")).string());
  if (rc != 0 && rc != static_cast<int>(ExitCode::QcFailed))
    return record(s, series, "failed " + n + "exit=" + std::to_string(rc) + " " + batch_support::first_error_line(log)), false;
  const std::string ids = store_outputs(s, out, study);
  char secs[32];
  std::snprintf(secs, sizeof secs, " seconds=%.1f", std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  record(s, series, std::string(rc == 0 ? "ok " : "qc_failed ") + n + "exit=" + std::to_string(rc) + ids + secs);
  return rc == 0;
}

// Series seen in the change log whose StableSeries has not come yet.
bool series_pending(const Service& s) {
  for (const Json& id : s.pacs.get_json("/series"))
    if (!s.pacs.get_json("/series/" + id.get<std::string>()).value("IsStable", true)) return true;
  return false;
}

// Follows /changes from the recorded position; returns the number of failed series.
int follow_changes(const Service& s, bool once, double poll_s) {
  long long seq = load_last_seq(s.work);
  int failed = 0;
  log_line(s, "following " + s.pacs.url() + "/changes from " + std::to_string(seq));
  while (!g_stop) {
    const Json page = s.pacs.get_json("/changes?since=" + std::to_string(seq) + "&limit=100");
    for (const Json& c : page.at("Changes")) {
      if (c.value("ChangeType", "") == "StableSeries") {
        const std::string id = c.value("ID", "");
        try {
          if (!process_series(s, id)) ++failed;
        } catch (const Error& e) {
          if (e.code() == ExitCode::Usage || e.code() == ExitCode::OutputFailed) throw;
          record(s, id, std::string("failed: ") + e.what());
          ++failed;
        }
      }
      seq = c.value("Seq", seq);
      save_last_seq(s, seq);
      if (g_stop) break;
    }
    seq = page.value("Last", seq);
    save_last_seq(s, seq);
    if (!page.value("Done", true)) continue;
    if (once && !series_pending(s)) break;
    std::this_thread::sleep_for(std::chrono::duration<double>(poll_s));
  }
  return failed;
}

}  // namespace

int orthanc_command(const cli::Args& args) {
  if (args.get("url").empty()) throw Error(ExitCode::Usage, "orthanc: --url is required");
  if (args.get("work").empty()) throw Error(ExitCode::Usage, "orthanc: --work WORKDIR is required");
  cli::Args run_args = cli::parse(run_spec(), [&] {
    std::vector<std::string> a = {"<input>", "-o", "<out>"};
    a.insert(a.end(), args.passthrough.begin(), args.passthrough.end());
    return a;
  }());
  check_run_options(run_args);
  std::string credentials;
  if (args.has("credentials")) {
    credentials = read_file_or_empty(args.get("credentials"));
    while (!credentials.empty() && (credentials.back() == '\n' || credentials.back() == '\r')) credentials.pop_back();
    if (credentials.find(':') == std::string::npos)
      throw Error(ExitCode::Usage, "--credentials " + args.get("credentials") + ": expected one line user:password");
  }
  const OrthancClient pacs(args.get("url"), credentials);
  Service s{pacs, fs::path(args.get("work")), args.passthrough, args.ranged("study-timeout", kDefaultStudyTimeoutS, "s")};
  std::error_code ec;
  fs::create_directories(s.work, ec);
  if (ec) throw Error(ExitCode::OutputFailed, s.work.string() + ": cannot create: " + ec.message());
  (void)pacs.get_json("/system");  // reachable, and the credentials work
  ::signal(SIGINT, on_stop);
  ::signal(SIGTERM, on_stop);
  const int failed = follow_changes(s, args.has("once"), args.ranged("poll", kDefaultPollS, "s"));
  log_line(s, "stopped; " + std::to_string(failed) + " series failed");
  return failed ? static_cast<int>(ExitCode::BatchIncomplete) : 0;
}

}  // namespace ms::pipeline
