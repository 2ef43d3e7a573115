#include "pipeline/staging.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>

#include "core/error.h"

namespace fs = std::filesystem;

namespace ms::pipeline {
namespace {

constexpr std::size_t kTokenHexDigits = 16;  // 64 random bits
constexpr std::size_t kMaxHostChars = 32;

std::string random_token() {
  std::random_device rd;  // /dev/urandom on Linux
  std::ostringstream s;
  s << std::hex;
  for (int i = 0; i < 4; ++i) {
    char b[5];
    std::snprintf(b, sizeof b, "%04x", static_cast<unsigned>(rd() & 0xffffu));
    s << b;
  }
  return s.str();
}

// The host name, reduced to characters safe in a file name.
std::string host_label() {
  char h[256] = {};
  if (::gethostname(h, sizeof h - 1) != 0) return "host";
  std::string out;
  for (const char* c = h; *c && out.size() < kMaxHostChars; ++c)
    out += (std::isalnum(static_cast<unsigned char>(*c)) || *c == '.' || *c == '_') ? *c : '_';
  return out.empty() ? "host" : out;
}

bool is_token(const std::string& s) {
  return s.size() == kTokenHexDigits && s.find_first_not_of("0123456789abcdef") == std::string::npos;
}

// An exclusive flock on OUTDIR/.mandisym.lock for the scope (blocking).
class OutdirLock {
 public:
  explicit OutdirLock(const fs::path& outdir) {
    fd_ = ::open((outdir / kOutdirLock).c_str(), O_RDWR | O_CREAT | O_NOFOLLOW | O_CLOEXEC, 0600);
    if (fd_ < 0) throw Error(ExitCode::OutputFailed, (outdir / kOutdirLock).string() + ": cannot open: " + std::strerror(errno));
    while (::flock(fd_, LOCK_EX) != 0 && errno == EINTR) {
    }
  }
  ~OutdirLock() { ::close(fd_); }
  OutdirLock(const OutdirLock&) = delete;
  OutdirLock& operator=(const OutdirLock&) = delete;

 private:
  int fd_ = -1;
};

bool owned_plain(const fs::path& p, bool want_dir) {
  struct stat st {};
  if (::lstat(p.c_str(), &st) != 0 || st.st_uid != ::geteuid()) return false;
  return want_dir ? S_ISDIR(st.st_mode) : S_ISREG(st.st_mode);
}

// Whether `dir` is a staging folder of a run that is gone: see staging.h.
bool is_stale_staging(const fs::path& dir) {
  const std::string name = dir.filename().string();
  const std::size_t dash = name.rfind('-');
  if (dash == std::string::npos || !is_token(name.substr(dash + 1))) return false;
  const fs::path marker = dir / kStagingMarker;
  if (!owned_plain(dir, true) || !owned_plain(marker, false)) return false;
  std::ifstream f(marker);
  std::stringstream text;
  text << f.rdbuf();
  if (text.str().find("token=" + name.substr(dash + 1) + "\n") == std::string::npos) return false;
  const int fd = ::open(marker.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) return false;
  const bool gone = ::flock(fd, LOCK_EX | LOCK_NB) == 0;  // its run held it until it ended
  ::close(fd);
  return gone;
}

}  // namespace

Staging::Staging(const std::string& outdir) : outdir_(outdir) {
  std::error_code ec;
  created_outdir_ = !fs::exists(outdir_, ec);
  fs::create_directories(outdir_, ec);
  if (ec || !fs::is_directory(outdir_, ec)) throw Error(ExitCode::OutputFailed, outdir + ": cannot create output folder" + (ec ? ": " + ec.message() : ""));
  token_ = random_token();
  dir_ = outdir_ / (std::string(kStagingPrefix) + host_label() + "-" + std::to_string(::getpid()) + "-" + token_);
  if (!fs::create_directory(dir_, ec) || ec)
    throw Error(ExitCode::OutputFailed, dir_.string() + ": cannot create" + (ec ? ": " + ec.message() : ""));
  const fs::path marker = dir_ / kStagingMarker;
  marker_fd_ = ::open(marker.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
  if (marker_fd_ < 0) throw Error(ExitCode::OutputFailed, marker.string() + ": cannot create: " + std::strerror(errno));
  const std::string text = "mandisym staging folder\ntoken=" + token_ + "\nhost=" + host_label() + "\npid=" + std::to_string(::getpid()) + "\n";
  if (::write(marker_fd_, text.data(), text.size()) != static_cast<ssize_t>(text.size()) || ::flock(marker_fd_, LOCK_EX) != 0)
    throw Error(ExitCode::OutputFailed, marker.string() + ": cannot write: " + std::strerror(errno));
  {
    OutdirLock lock(outdir_);
    remove_stale();
  }
  fs::create_directories(dir_ / "qc", ec);
  if (ec) throw Error(ExitCode::OutputFailed, dir_.string() + ": cannot create: " + ec.message());
}

Staging::~Staging() {
  if (committed_) return;
  std::error_code ec;
  fs::remove_all(dir_, ec);
  if (marker_fd_ >= 0) ::close(marker_fd_);
  if (!created_outdir_) return;
  // OUTDIR was made by this run: remove it when nothing but the lock is left.
  std::size_t others = 0;
  for (const auto& e : fs::directory_iterator(outdir_, ec))
    if (e.path().filename() != kOutdirLock) ++others;
  if (!ec && others == 0) {
    fs::remove(outdir_ / kOutdirLock, ec);
    fs::remove(outdir_, ec);
  }
}

void Staging::remove_stale() const {
  std::error_code ec;
  std::vector<fs::path> stale;
  for (const auto& e : fs::directory_iterator(outdir_, ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(kStagingPrefix, 0) != 0 || e.path() == dir_) continue;
    if (is_stale_staging(e.path())) stale.push_back(e.path());
  }
  for (const auto& p : stale) fs::remove_all(p, ec);
}

void Staging::commit() {
  OutdirLock lock(outdir_);
  std::error_code ec;
  auto fail = [](const fs::path& p, const std::error_code& e) {
    throw Error(ExitCode::OutputFailed, p.string() + ": cannot move into place: " + e.message());
  };
  // 1. The marker of a complete run goes first.
  fs::remove(outdir_ / "results.json", ec);
  if (ec) fail(outdir_ / "results.json", ec);
  // 2. Every other output; a folder (qc/) replaces the old one whole.
  for (const auto& entry : fs::directory_iterator(dir_)) {
    const fs::path name = entry.path().filename();
    if (name == "results.json" || name == kStagingMarker) continue;
    const fs::path target = outdir_ / name;
    if (entry.is_directory() && fs::symlink_status(target, ec).type() == fs::file_type::directory) fs::remove_all(target, ec);
    fs::rename(entry.path(), target, ec);
    if (ec) fail(target, ec);
  }
  // 3. results.json last.
  fs::rename(dir_ / "results.json", outdir_ / "results.json", ec);
  if (ec) fail(outdir_ / "results.json", ec);
  fs::remove_all(dir_, ec);
  ::close(marker_fd_);
  marker_fd_ = -1;
  committed_ = true;
}

}  // namespace ms::pipeline
