// See batch_support.h.
#include "pipeline/batch_support.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <regex>
#include <sstream>

#include "core/error.h"
#include "core/digest.h"

namespace fs = std::filesystem;

namespace ms::pipeline::batch_support {

std::int64_t study_bytes(const fs::path& p) {
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0) return -1;
  if (S_ISREG(st.st_mode)) return static_cast<std::int64_t>(st.st_size);
  if (!S_ISDIR(st.st_mode)) return -1;  // FIFO, device, socket: unknown
  std::int64_t total = 0;
  std::size_t seen = 0;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(p, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::recursive_directory_iterator() && seen < kMaxSizedEntries; it.increment(ec), ++seen) {
    std::error_code e2;
    if (it->is_regular_file(e2)) total += static_cast<std::int64_t>(it->file_size(e2));
  }
  return total;
}

double default_timeout_s(std::int64_t bytes) {
  return kDefaultStudyTimeoutS + (bytes > 0 ? kStudyTimeoutSPerMB * static_cast<double>(bytes) / 1e6 : 0.0);
}

std::string deidentify_key(const fs::path& out) {
  const fs::path kp = out / ".deidentify-key";
  {
    std::ifstream f(kp);
    std::string key;
    if (f && std::getline(f, key) && key.size() == 64) return key;
  }
  unsigned char raw[32];
  std::ifstream rnd("/dev/urandom", std::ios::binary);
  if (!rnd.read(reinterpret_cast<char*>(raw), sizeof raw)) throw Error(ExitCode::Internal, "/dev/urandom: cannot read");
  std::string key;
  char hx[3];
  for (unsigned char c : raw) std::snprintf(hx, sizeof hx, "%02x", c), key += hx;
  const int fd = ::open(kp.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0600);
  if (fd < 0) throw Error(ExitCode::OutputFailed, kp.string() + ": cannot create the pseudonymisation key");
  const std::string line = key + "\n";
  const bool ok = ::write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size());
  ::close(fd);
  if (!ok) throw Error(ExitCode::OutputFailed, kp.string() + ": cannot write the pseudonymisation key");
  return key;
}

std::string pseudonym(const std::string& key, const std::string& name) {
  Sha256 h;
  h.update(key.data(), key.size());
  h.update(name.data(), name.size());
  return "s" + h.hex_digest().substr(0, 16);
}

std::vector<std::string> identifying_strings(const fs::path& p, const std::string& name) {
  std::vector<std::string> v = {p.string(), name, p.filename().string()};
  std::error_code ec;
  const fs::path a = fs::absolute(p, ec);
  if (!ec) v.push_back(a.string()), v.push_back(a.lexically_normal().string());
  const fs::path c = fs::weakly_canonical(p, ec);
  if (!ec) v.push_back(c.string()), v.push_back(c.filename().string());
  for (auto& s : v)
    while (s.size() > 1 && s.back() == '/') s.pop_back();
  // Longest first, so that a path is replaced whole before its last part.
  std::sort(v.begin(), v.end(), [](const std::string& x, const std::string& y) { return x.size() > y.size(); });
  v.erase(std::unique(v.begin(), v.end()), v.end());
  v.erase(std::remove_if(v.begin(), v.end(), [](const std::string& s) { return s.size() < 3; }), v.end());
  return v;
}

std::string scrub(const std::string& text, const std::vector<std::string>& identifying, const std::string& id) {
  std::string s = text;
  for (const auto& w : identifying)
    for (std::size_t p = s.find(w); p != std::string::npos; p = s.find(w, p + id.size())) s.replace(p, w.size(), id);
  static const std::regex path(R"((^|[\s'"(=:,])/[^\s'",)]+)");
  static const std::regex uid(R"(\b\d+(\.\d+){3,}\b)");
  static const std::regex date(R"(\b(19|20)\d\d(0[1-9]|1[0-2])(0[1-9]|[12]\d|3[01])\b)");
  s = std::regex_replace(s, path, "$1<path>");
  s = std::regex_replace(s, uid, "<uid>");
  s = std::regex_replace(s, date, "<date>");
  return s;
}

std::string self_exe() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("mandisym") : p.string();
}

std::string first_error_line(const std::string& text) {
  std::istringstream f(text);
  std::string line, last;
  while (std::getline(f, line))
    if (line.find("error") != std::string::npos) return line;
    else if (!line.empty()) last = line;
  return last;
}


}  // namespace ms::pipeline::batch_support
