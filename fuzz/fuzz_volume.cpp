// libFuzzer entry for volume-file ingest (NIfTI, NRRD, MetaImage): the first
// byte picks the format, the rest becomes one file with that extension, which
// goes through what `mandisym run FILE` and `--mask FILE` do with it:
// io::read_scan (our header and payload checks, then ITK's reader) and
// io::read_mask / io::read_label_map. An ms::Error is an accepted outcome; a
// crash, a sanitizer report, an uncaught exception, a hang or an allocation
// beyond libFuzzer's RSS limit is a finding.

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.h"
#include "io/volume_io.h"

namespace fs = std::filesystem;

namespace {
const char* const kExtensions[] = {".nii", ".nrrd", ".mha", ".nii.gz"};
constexpr std::size_t kFormats = sizeof(kExtensions) / sizeof(kExtensions[0]);

const fs::path& workdir() {
  // A fixed name: the path reaches the code under test (error messages), and
  // libFuzzer's comparison tracing would make runs differ between machines.
  static const fs::path d = [] {
    const fs::path p = fs::temp_directory_path() / "mandisym_fuzz_volume";
    fs::create_directories(p);
    return p;
  }();
  return d;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const fs::path file = workdir() / (std::string("volume") + kExtensions[data[0] % kFormats]);
  {
    std::ofstream f(file, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data + 1), static_cast<std::streamsize>(size - 1));
  }
  try {
    ms::io::read_scan(file.string());
  } catch (const ms::Error&) {
  }
  try {
    ms::io::read_mask(file.string());
  } catch (const ms::Error&) {
  }
  try {
    ms::io::read_label_map(file.string());
  } catch (const ms::Error&) {
  }
  std::error_code ec;
  fs::remove(file, ec);
  return 0;
}
