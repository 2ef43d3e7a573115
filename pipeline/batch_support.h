// `mandisym batch`: per-study timeouts, pseudonymous ids and scrubbing of
// error text under --deidentify (docs/batch.md, "Timeouts" and
// "De-identified cohorts").
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace ms::pipeline::batch_support {

// Per-study timeout when --study-timeout is not given, s: 600 s plus 1 s per
// MB of the study's files. The slowest documented end-to-end run is ~13 s for
// a 512² × 300 scan (~160 MB, README "Speed", on a slow host: ~0.08 s/MB);
// 1 s/MB is a 12× margin for large scans and the 600 s floor a 45× margin for
// the fixed costs (atlas fit, report). Studies of unknown size (a FIFO, a
// device, unreadable) get the floor.
constexpr double kDefaultStudyTimeoutS = 600.0;
constexpr double kStudyTimeoutSPerMB = 1.0;
// After the timeout (or Ctrl-C), the study's process group gets SIGTERM (run
// cleans its Xvfb); SIGKILL follows after this grace, s.
constexpr double kKillGraceS = 5.0;
// Most directory entries walked to size a study (a symlink loop or a huge
// tree must not stall the cohort); beyond it the size counted so far is used.
constexpr std::size_t kMaxSizedEntries = 200000;

// Bytes of regular files in the study (a file, or a folder walked
// recursively, never opening anything); -1 when unknown.
std::int64_t study_bytes(const std::filesystem::path& p);
// The default timeout for a study of that size (bytes < 0: unknown), s.
double default_timeout_s(std::int64_t bytes);

// The cohort's pseudonymisation key: 32 random bytes as hex in
// OUT/.deidentify-key (created 0600 on first use, kept for resuming).
std::string deidentify_key(const std::filesystem::path& out);
// Pseudonymous study id: "s" + the first 16 hex of SHA-256(key + name).
std::string pseudonym(const std::string& key, const std::string& name);

// Text with everything that can identify the study removed: each of
// `identifying` (its path as given, absolute and canonical, its name) becomes
// `id`; then any remaining absolute path becomes <path>, DICOM UIDs (4+
// dot-separated numbers) <uid> and dates (YYYYMMDD, 1900-2099) <date>.
std::string scrub(const std::string& text, const std::vector<std::string>& identifying, const std::string& id);
// The strings `scrub` replaces for a study given by path p with name `name`.
std::vector<std::string> identifying_strings(const std::filesystem::path& p, const std::string& name);

// This executable's path (for starting `mandisym run`); "mandisym" when unknown.
std::string self_exe();
// The line of a study's log that says why it failed: the first line naming an
// error, else the last non-empty line.
std::string first_error_line(const std::string& log);

}  // namespace ms::pipeline::batch_support
