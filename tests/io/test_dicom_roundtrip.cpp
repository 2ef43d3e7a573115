// DICOM write -> read through ITK/GDCM: same HU values, same LPS geometry,
// same spacing; for uncompressed and both lossless compressed syntaxes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <unistd.h>

#include "core/error.h"
#include "io/volume_io.h"

namespace fs = std::filesystem;
using namespace ms;

namespace {

fs::path temp_dir(const std::string& name) {
  fs::path p = fs::temp_directory_path() / ("mandisym_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

Volume test_volume(bool oblique) {
  Volume v;
  v.geom.size = {24, 20, 9};
  v.geom.spacing = {0.61, 0.73, 1.25};
  v.geom.origin = {-71.3, 12.9, -204.5};
  if (oblique) {
    // Orthonormal, not axis-aligned (tilted acquisition plane).
    const double a = 0.3, b = 0.2;
    const Vec3 c0 = normalized(Vec3{std::cos(a), std::sin(a), 0});
    const Vec3 c1 = normalized(cross(Vec3{0, -std::sin(b), std::cos(b)}, c0));
    const Vec3 c2 = cross(c0, c1);
    v.geom.direction = {c0[0], c1[0], c2[0], c0[1], c1[1], c2[1], c0[2], c1[2], c2[2]};
  }
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> hu(-1024, 3071);
  v.hu.resize(v.geom.voxel_count());
  for (auto& x : v.hu) x = static_cast<float>(hu(rng));
  v.hu[0] = -1024;
  v.hu[1] = 3071;
  v.hu[2] = 0;
  return v;
}

void expect_same(const Volume& a, const Volume& b) {
  ASSERT_EQ(a.geom.size, b.geom.size);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(a.geom.spacing[k], b.geom.spacing[k], 1e-4);
    EXPECT_NEAR(a.geom.origin[k], b.geom.origin[k], 1e-3);
  }
  for (int k = 0; k < 9; ++k) EXPECT_NEAR(a.geom.direction[k], b.geom.direction[k], 1e-5);
  // LPS position of the far corner voxel agrees.
  const Vec3 pa = a.geom.index_to_lps(23, 19, 8), pb = b.geom.index_to_lps(23, 19, 8);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(pa[k], pb[k], 1e-3);
  ASSERT_EQ(a.hu.size(), b.hu.size());
  std::size_t diff = 0;
  for (std::size_t i = 0; i < a.hu.size(); ++i) diff += a.hu[i] != b.hu[i];
  EXPECT_EQ(diff, 0u);
}

}  // namespace

class DicomRoundTrip : public ::testing::TestWithParam<std::pair<std::string, bool>> {};

TEST_P(DicomRoundTrip, SameValuesAndGeometry) {
  const auto [compression, oblique] = GetParam();
  const fs::path dir = temp_dir("rt_" + compression + (oblique ? "_obl" : ""));
  const Volume v = test_volume(oblique);
  io::DicomSeriesSpec spec;
  spec.compression = compression;
  const std::string uid = io::write_dicom_series(v, spec, (dir / "series").string());
  EXPECT_EQ(std::distance(fs::directory_iterator(dir / "series"), fs::directory_iterator{}), 9);
  const io::LoadedScan back = io::read_scan((dir / "series").string());
  expect_same(v, back.volume);
  EXPECT_EQ(back.info.kind, "dicom");
  EXPECT_EQ(back.info.modality, "CT");
  EXPECT_EQ(back.info.series_uid, uid);
  EXPECT_EQ(back.info.file_count, 9u);
  EXPECT_EQ(back.info.pixel_sha256.size(), 64u);
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Syntaxes, DicomRoundTrip,
                         ::testing::Values(std::make_pair(std::string("raw"), false),
                                           std::make_pair(std::string("raw"), true),
                                           std::make_pair(std::string("jpeg-lossless"), false),
                                           std::make_pair(std::string("jpeg2000"), true)));

TEST(DicomRoundTrip, SlicesAreOrderedByPositionNotFileName) {
  const fs::path dir = temp_dir("order");
  const Volume v = test_volume(false);
  io::write_dicom_series(v, {}, (dir / "s").string());
  // Rename the files so that name order is the reverse of position order.
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir / "s")) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (std::size_t i = 0; i < files.size(); ++i)
    fs::rename(files[i], dir / "s" / ("z" + std::to_string(100 - i) + ".dcm"));
  const io::LoadedScan back = io::read_scan((dir / "s").string());
  expect_same(v, back.volume);
  fs::remove_all(dir);
}

TEST(NiftiMask, RoundTripKeepsGridAndValues) {
  const fs::path dir = temp_dir("mask");
  Mask m;
  m.geom = test_volume(true).geom;
  m.data.assign(m.geom.voxel_count(), 0);
  for (std::size_t i = 0; i < m.data.size(); i += 7) m.data[i] = 1;
  io::write_mask(m, (dir / "m.nii.gz").string());
  const Mask back = io::read_mask((dir / "m.nii.gz").string());
  EXPECT_TRUE(back.geom.same_grid(m.geom, 1e-4));
  EXPECT_EQ(back.data, m.data);
  fs::remove_all(dir);
}

// A float file used as a mask (a probability map, a CT by mistake) is
// thresholded at != 0 on its own values, not narrowed to uint8 first (found
// by fuzzing: ITK's float->uint8 conversion of -1000 is undefined behaviour,
// and 0.4 became 0). Non-finite values and non-label values are refused.
TEST(NiftiMask, FloatFileIsThresholdedOnItsOwnValues) {
  const fs::path dir = temp_dir("fmask");
  Volume v = test_volume(false);
  for (std::size_t i = 0; i < v.hu.size(); ++i) v.hu[i] = i % 3 == 0 ? 0.0f : i % 3 == 1 ? -1000.0f : 0.4f;
  for (const char* ext : {".nii.gz", ".nrrd"}) {
    const std::string f = (dir / (std::string("p") + ext)).string();
    io::write_volume(v, f);
    const Mask m = io::read_mask(f);
    ASSERT_EQ(m.data.size(), v.hu.size()) << ext;
    for (std::size_t i = 0; i < m.data.size(); ++i) ASSERT_EQ(m.data[i], i % 3 == 0 ? 0 : 1) << ext << " voxel " << i;
    const LabelMap l = io::read_label_map(f);
    EXPECT_EQ(l.labels[1], -1000) << ext;
    EXPECT_EQ(l.labels[2], 0) << ext;
  }
  v.hu[5] = std::numeric_limits<float>::quiet_NaN();
  io::write_volume(v, (dir / "nan.nrrd").string());
  v.hu[5] = 3e9f;
  io::write_volume(v, (dir / "huge.nrrd").string());
  auto refused = [&](auto read, const char* f) {
    try {
      read((dir / f).string());
    } catch (const Error& e) {
      return e.code() == ExitCode::InputInvalid;
    }
    return false;
  };
  EXPECT_TRUE(refused(io::read_mask, "nan.nrrd"));
  EXPECT_TRUE(refused(io::read_label_map, "nan.nrrd"));
  EXPECT_TRUE(refused(io::read_label_map, "huge.nrrd"));
  EXPECT_EQ(io::read_mask((dir / "huge.nrrd").string()).data[5], 1);  // finite and != 0: inside
  fs::remove_all(dir);
}

TEST(ReadScan, MissingPathIsInputNotFound) {
  try {
    io::read_scan("/nonexistent/mandisym/path");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ExitCode::InputNotFound);
    EXPECT_NE(std::string(e.what()).find("/nonexistent/mandisym/path"), std::string::npos);
  }
}

TEST(ReadScan, FolderWithoutDicomIsInputInvalid) {
  const fs::path dir = temp_dir("nodicom");
  std::ofstream(dir / "notes.txt") << "not a DICOM file\n";
  try {
    io::read_scan(dir.string());
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ExitCode::InputInvalid);
  }
  fs::remove_all(dir);
}

TEST(ReadScan, HuOffsetIsAppliedToVolumeFiles) {
  const fs::path dir = temp_dir("offset");
  // Write the mask writer's NIfTI as a stand-in volume file with values 0/1.
  Mask m;
  m.geom = test_volume(false).geom;
  m.data.assign(m.geom.voxel_count(), 1);
  io::write_mask(m, (dir / "v.nii.gz").string());
  io::ReadOptions ro;
  ro.hu_offset = -1024;
  const io::LoadedScan s = io::read_scan((dir / "v.nii.gz").string(), ro);
  EXPECT_EQ(s.info.kind, "nifti");
  EXPECT_FLOAT_EQ(s.volume.hu[5], -1023.0f);
  fs::remove_all(dir);
}
