// Writes seed DICOM files for fuzz_dicom: one slice per transfer syntax the
// forge writes and an enhanced multi-frame CT (usable on its own, so pixel
// decoding is reached).
#include <filesystem>
#include <string>

#include "tests/support/dicom_forge.h"

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  const std::filesystem::path out = argv[1];
  std::filesystem::create_directories(out);
  ms::testing::SliceSpec s;
  s.rows = 8;
  s.cols = 10;
  s.stored.assign(80, 0);
  for (std::size_t i = 0; i < s.stored.size(); ++i) s.stored[i] = static_cast<std::int32_t>(900 + (37 * i) % 400);
  for (const char* ts : {"raw", "implicit", "jpeg-lossless", "jpeg2000", "rle"}) {
    s.transfer_syntax = ts;
    ms::testing::write_slice((out / (std::string(ts) + ".dcm")).string(), s);
  }
  ms::testing::EnhancedSpec e;
  e.base = s;
  e.base.transfer_syntax = "raw";
  for (int k = 0; k < 6; ++k) {
    e.ipps.push_back({0, 0, static_cast<double>(k)});
    e.frames.push_back(s.stored);
  }
  ms::testing::write_enhanced((out / "enhanced.dcm").string(), e);
  return 0;
}
