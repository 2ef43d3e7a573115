// Where `run` writes its outputs before they are moved into OUTDIR
// (docs/security.md, "Output folder"). A run's outputs appear in OUTDIR only
// when every stage succeeded, and a reader that finds results.json finds the
// outputs that belong to it.
//
// - The staging folder is OUTDIR/.mandisym-partial-<host>-<pid>-<token>: its
//   name is unique across hosts and containers sharing OUTDIR.
// - It holds a marker file (kStagingMarker) naming the project, the random
//   token, host and pid, and the run holds an exclusive flock on that marker
//   for its whole life. A staging folder is stale, and removed by the next
//   run, only when its marker carries the token in its name, it and its
//   marker are owned by this user, neither is a symbolic link, and the marker's
//   lock can be taken (its run is gone, whatever its PID namespace or host).
//   Anything else named like a staging folder is left alone.
// - OUTDIR/.mandisym.lock is flocked while stale folders are removed and
//   while a run commits, so two runs never interleave their commits.
// - commit(): results.json is removed first, then every output is moved into
//   place (qc/ replaced whole), then results.json last.
#pragma once

#include <filesystem>
#include <string>

namespace ms::pipeline {

constexpr const char* kStagingPrefix = ".mandisym-partial-";
constexpr const char* kStagingMarker = ".mandisym-staging";
constexpr const char* kOutdirLock = ".mandisym.lock";

class Staging {
 public:
  // Creates OUTDIR (if needed) and the staging folder; removes stale ones.
  // Throws ms::Error(OutputFailed) when OUTDIR cannot be written.
  explicit Staging(const std::string& outdir);
  Staging(const Staging&) = delete;
  Staging& operator=(const Staging&) = delete;
  // Removes the staging folder unless committed, and OUTDIR when this run
  // created it and it is empty.
  ~Staging();

  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  const std::filesystem::path& dir() const { return dir_; }

  // Moves the outputs into OUTDIR (see above). Throws ms::Error(OutputFailed).
  void commit();

 private:
  void remove_stale() const;

  std::filesystem::path outdir_, dir_;
  std::string token_;
  int marker_fd_ = -1;
  bool created_outdir_ = false, committed_ = false;
};

}  // namespace ms::pipeline
