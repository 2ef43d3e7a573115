#include "core/files.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace ms {

void write_file_atomic(const std::string& path, const std::string& bytes) {
  const std::string tmp = path + ".partial";
  std::error_code ec;
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    f.close();  // a full disk shows when the buffer is flushed, at the latest here
    if (!f) {
      std::filesystem::remove(tmp, ec);
      throw Error(ExitCode::OutputFailed, path + ": cannot write (disk full or not writable)");
    }
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw Error(ExitCode::OutputFailed, path + ": cannot write: " + ec.message());
  }
}

std::string read_file_or_empty(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

}  // namespace ms
