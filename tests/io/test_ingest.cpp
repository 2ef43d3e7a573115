// Ingest of DICOM as real archives deliver it: files forged with GDCM, read
// through ms::io::read_scan, compared with the known HU field.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "io/dicom.h"
#include "io/volume_io.h"
#include "tests/support/dicom_forge.h"

namespace fs = std::filesystem;
using namespace ms;
using ms::testing::SliceSpec;

namespace {

fs::path temp_dir(const std::string& name) {
  fs::path p = fs::temp_directory_path() / ("mandisym_ingest_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

// A linear HU field: linear interpolation reproduces it exactly, so resampled
// volumes can be checked voxel by voxel.
double field(const Vec3& p) { return 100.0 + 3.0 * p[0] - 2.0 * p[1] + 5.0 * p[2]; }

// Every voxel of v holds field(position) within tol (voxels outside the data,
// set to air, are skipped when skip_air).
void expect_field(const Volume& v, double tol, bool skip_air = false) {
  std::size_t bad = 0, checked = 0;
  for (std::size_t k = 0; k < v.geom.size[2]; ++k)
    for (std::size_t j = 0; j < v.geom.size[1]; ++j)
      for (std::size_t i = 0; i < v.geom.size[0]; ++i) {
        const float h = v.hu[v.geom.linear(i, j, k)];
        if (skip_air && h <= -1024.0f) continue;
        ++checked;
        const double want = std::max(-1024.0, field(v.geom.index_to_lps(i, j, k)));
        if (std::abs(h - want) > tol) ++bad;
      }
  EXPECT_EQ(bad, 0u) << "of " << checked << " voxels";
  EXPECT_GT(checked, v.hu.size() / 2);
}

}  // namespace

class Syntax : public ::testing::TestWithParam<std::string> {};

TEST_P(Syntax, SeriesDecodesToTheSameHu) {
  const fs::path dir = temp_dir("syntax_" + GetParam());
  SliceSpec base;
  base.transfer_syntax = GetParam();
  ms::testing::write_series(dir.string(), base, 10, -20.0, 2.0, field);
  const auto s = io::read_scan(dir.string());
  EXPECT_EQ(s.volume.geom.size[2], 10u);
  EXPECT_NEAR(s.volume.geom.spacing[2], 2.0, 1e-6);
  expect_field(s.volume, 0.51);  // stored values are rounded to integers
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Ingest, Syntax, ::testing::Values("raw", "implicit", "jpeg-lossless", "jpeg2000", "rle"));

TEST(Ingest, EnhancedMultiFrameEqualsSingleFrameSeries) {
  const fs::path dir = temp_dir("enhanced");
  ms::testing::EnhancedSpec e;
  e.base.intercept = -1000;
  e.base.slope = 0.5;
  for (int k = 0; k < 12; ++k) {
    const Vec3 ipp{-5, 3, 40.0 - 1.5 * k};  // frames stored top to bottom
    e.ipps.push_back(ipp);
    std::vector<std::int32_t> f;
    for (unsigned j = 0; j < e.base.rows; ++j)
      for (unsigned i = 0; i < e.base.cols; ++i)
        f.push_back(ms::testing::stored_for(e.base, field(ipp + Vec3{i * e.base.spacing_i, j * e.base.spacing_j, 0})));
    e.frames.push_back(f);
  }
  ms::testing::write_enhanced((dir / "enhanced.dcm").string(), e);
  for (const std::string& path : {dir.string(), (dir / "enhanced.dcm").string()}) {
    const auto s = io::read_scan(path);
    EXPECT_EQ(s.volume.geom.size[2], 12u);
    EXPECT_NEAR(s.volume.geom.spacing[2], 1.5, 1e-6);
    expect_field(s.volume, 0.51);
  }
  fs::remove_all(dir);
}
