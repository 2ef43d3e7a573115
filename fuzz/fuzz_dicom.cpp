// libFuzzer entry for DICOM ingest: the bytes become one file in a folder,
// which goes through what `mandisym run` does with a folder: header scan,
// series grouping, geometry analysis, series choice and, for a usable series
// (e.g. an enhanced multi-frame file), pixel decoding and assembly. An
// ms::Error is an accepted outcome; a crash, a sanitizer report, an uncaught
// exception or a hang is a finding.

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "io/dicom.h"

namespace fs = std::filesystem;
namespace dicom = ms::io::dicom;

static const fs::path& workdir() {
  // A fixed name: the path reaches the code under test (error messages), and
  // libFuzzer's comparison tracing would make runs differ between machines.
  static const fs::path d = [] {
    const fs::path p = fs::temp_directory_path() / "mandisym_fuzz_dicom";
    fs::create_directories(p);
    return p;
  }();
  return d;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const fs::path file = workdir() / "slice.dcm";
  {
    std::ofstream f(file, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  try {
    const dicom::ScanResult sc = dicom::scan(workdir().string());
    std::vector<dicom::Layout> layouts;
    for (const auto& s : sc.series) layouts.push_back(dicom::analyse(s));
    std::string why;
    const int chosen = dicom::choose(sc, layouts, &why);
    if (chosen >= 0) {
      std::vector<std::string> warnings;
      dicom::assemble(sc.series[static_cast<std::size_t>(chosen)], layouts[static_cast<std::size_t>(chosen)], warnings);
    }
  } catch (const ms::Error&) {
  }
  std::error_code ec;
  fs::remove(file, ec);
  return 0;
}
