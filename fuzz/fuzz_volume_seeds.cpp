// Writes seed files for fuzz_volume: a small oblique float volume in each
// format the product reads (NIfTI, NRRD, MetaImage; NIfTI also gzipped) and a
// uint8 mask, each prefixed by the format byte fuzz_volume expects.
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "io/volume_io.h"

namespace fs = std::filesystem;

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  const fs::path out = argv[1];
  fs::create_directories(out);
  ms::Volume v;
  v.geom.size = {6, 5, 4};
  v.geom.spacing = {0.8, 0.9, 2.5};
  v.geom.origin = {-10, 20, -30};
  v.geom.direction = {0.96, -0.28, 0, 0.28, 0.96, 0, 0, 0, 1};
  v.hu.resize(v.geom.voxel_count());
  for (std::size_t i = 0; i < v.hu.size(); ++i) v.hu[i] = static_cast<float>(-1000 + 37 * static_cast<int>(i % 60));
  ms::Mask m;
  m.geom = v.geom;
  m.data.assign(v.geom.voxel_count(), 0);
  for (std::size_t i = 0; i < m.data.size(); i += 3) m.data[i] = 1;
  const char* const ext[] = {".nii", ".nrrd", ".mha", ".nii.gz"};
  const fs::path tmp = out / "tmp";
  fs::create_directories(tmp);
  for (int f = 0; f < 4; ++f) {
    const fs::path vol = tmp / (std::string("volume") + ext[f]);
    ms::io::write_volume(v, vol.string());
    fs::path files[2] = {vol, {}};
    if (f == 0 || f == 3) {
      files[1] = tmp / (std::string("mask") + ext[f]);
      ms::io::write_mask(m, files[1].string());
    }
    for (const fs::path& p : files) {
      if (p.empty()) continue;
      std::ifstream in(p, std::ios::binary);
      const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      std::ofstream o(out / (p.filename().string() + ".seed"), std::ios::binary);
      o.put(static_cast<char>(f));
      o << bytes;
    }
  }
  fs::remove_all(tmp);
  // Headers with the data-file forms and encodings fuzz_volume provides
  // files for (format byte 0xFE: .nhdr, 0xFF: .mhd; 1: .nrrd, 2: .mha attached).
  const std::string nrrd = "NRRD0004\ntype: float\ndimension: 3\nspace: left-posterior-superior\nsizes: 6 5 4\n"
                           "space directions: (0.8,0,0) (0,0.9,0) (0,0,2.5)\nendian: little\n";
  const std::string meta = "ObjectType = Image\nNDims = 3\nDimSize = 6 5 4\nElementSpacing = 0.8 0.9 2.5\n"
                           "ElementType = MET_FLOAT\n";
  std::string raw(6 * 5 * 4 * 4, '\0');
  for (std::size_t i = 0; i < raw.size() / 4; ++i) {
    const float x = static_cast<float>(-1000 + 37 * static_cast<int>(i % 60));
    std::memcpy(&raw[i * 4], &x, 4);
  }
  const std::pair<const char*, std::string> headers[] = {
      {"nhdr_raw", "\xfe" + nrrd + "encoding: raw\ndata file: data.raw\n"},
      {"nhdr_gzip", "\xfe" + nrrd + "encoding: gzip\ndata file: data.gz\n"},
      {"nhdr_list", "\xfe" + nrrd + "encoding: raw\ndata file: LIST 2\ndata1.raw\ndata2.raw\n"},
      {"nhdr_pattern", "\xfe" + nrrd + "encoding: raw\ndata file: data%d.raw 1 2 1 2\n"},
      {"nhdr_outside", "\xfe" + nrrd + "encoding: raw\ndata file: ../outside.raw\n"},
      {"nhdr_short", "\xfe" + nrrd + "encoding: raw\ndata file: data1.raw\n"},
      {"mhd_raw", "\xff" + meta + "ElementDataFile = data.raw\n"},
      {"mhd_zlib_fake", "\xff" + meta + "CompressedData = True\nElementDataFile = data.raw\n"},
      {"mhd_list", "\xff" + meta + "ElementDataFile = LIST 2\ndata1.raw\ndata2.raw\n"},
      {"mhd_pattern", "\xff" + meta + "ElementDataFile = data%d.raw 1 2 1 2\n"},
      {"mhd_outside", "\xff" + meta + "ElementDataFile = ../outside.raw\n"},
      {"nrrd_raw_attached", "\x01" + nrrd + "encoding: raw\n\n" + raw},
      {"mha_raw_attached", "\x02" + meta + "ElementDataFile = LOCAL\n" + raw},
  };
  for (const auto& [name, bytes] : headers) std::ofstream(out / (std::string(name) + ".seed"), std::ios::binary) << bytes;
  return 0;
}
