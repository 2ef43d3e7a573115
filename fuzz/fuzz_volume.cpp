// libFuzzer entry for volume-file ingest (NIfTI, NRRD, MetaImage): the first
// byte picks the format (0xFE: .nhdr, 0xFF: .mhd, else the byte modulo 4 into
// .nii .nrrd .mha .nii.gz, as the stored regressions were written), the rest
// becomes one file with that extension. The detached formats find data files next to them: data.raw (raw
// float32 voxels), data.gz (the same, gzip), data1.raw / data2.raw (for LIST
// and %d patterns) and, one folder up, outside.raw (refused unless allowed),
// so the data-file, confinement and compressed-stream checks are driven too.
// Each file goes through what `mandisym run FILE` and `--mask FILE` do with it:
// io::read_scan (our header and payload checks, then ITK's reader) and
// io::read_mask / io::read_label_map. An ms::Error is an accepted outcome; a
// crash, a sanitizer report, an uncaught exception, a hang or an allocation
// beyond libFuzzer's RSS limit is a finding.

#include <zlib.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.h"
#include "io/volume_io.h"

namespace fs = std::filesystem;

namespace {
const char* const kExtensions[] = {".nii", ".nrrd", ".mha", ".nii.gz"};
constexpr std::size_t kFormats = sizeof(kExtensions) / sizeof(kExtensions[0]);

// The data files a detached header may name (6 x 5 x 4 float32, as the seeds).
void write_data_files(const fs::path& dir) {
  std::string raw(6 * 5 * 4 * 4, '\0');
  for (std::size_t i = 0; i < raw.size() / 4; ++i) {
    const float v = static_cast<float>(-1000 + 37 * static_cast<int>(i % 60));
    std::memcpy(&raw[i * 4], &v, 4);
  }
  std::ofstream(dir / "data.raw", std::ios::binary) << raw;
  std::ofstream(dir / "data1.raw", std::ios::binary) << raw.substr(0, raw.size() / 2);
  std::ofstream(dir / "data2.raw", std::ios::binary) << raw.substr(raw.size() / 2);
  std::ofstream(dir.parent_path() / "outside.raw", std::ios::binary) << raw;
  gzFile gz = gzopen((dir / "data.gz").c_str(), "wb");
  gzwrite(gz, raw.data(), static_cast<unsigned>(raw.size()));
  gzclose(gz);
}

const fs::path& workdir() {
  // A fixed name: the path reaches the code under test (error messages), and
  // libFuzzer's comparison tracing would make runs differ between machines.
  static const fs::path d = [] {
    const fs::path p = fs::temp_directory_path() / "mandisym_fuzz_volume" / "case";
    fs::create_directories(p);
    write_data_files(p);
    return p;
  }();
  return d;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const char* ext = data[0] == 0xFE ? ".nhdr" : data[0] == 0xFF ? ".mhd" : kExtensions[data[0] % kFormats];
  const fs::path file = workdir() / (std::string("volume") + ext);
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
