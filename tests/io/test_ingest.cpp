// Ingest of DICOM as real archives deliver it: files forged with GDCM, read
// through ms::io::read_scan, compared with the known HU field.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <zlib.h>

#include "core/error.h"
#include "io/dicom.h"
#include "core/array_order.h"
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

namespace {

bool has_warning(const io::LoadedScan& s, const std::string& needle) {
  for (const auto& w : s.info.warnings)
    if (w.find(needle) != std::string::npos) return true;
  return false;
}

}  // namespace

TEST(Ingest, CompressedFilesReallyCarryTheirTransferSyntax) {
  const fs::path dir = temp_dir("ts");
  SliceSpec base;
  base.transfer_syntax = "rle";
  ms::testing::write_series(dir.string(), base, 8, 0.0, 1.0, field);
  const auto sc = io::dicom::scan(dir.string());
  ASSERT_EQ(sc.series.size(), 1u);
  EXPECT_EQ(sc.series[0].transfer_syntax.substr(0, 22), "1.2.840.10008.1.2.5");  // RLE Lossless
  fs::remove_all(dir);
}

TEST(Ingest, GantryTiltIsResampledOntoAnOrthogonalGrid) {
  const fs::path dir = temp_dir("tilt");
  SliceSpec base;
  const double tilt = 15.0 * 3.14159265358979 / 180.0, dz = 1.5;
  for (int k = 0; k < 14; ++k) {
    SliceSpec s = base;
    // Tilted acquisition: each slice shifts along the column direction.
    s.ipp = Vec3{0, k * dz * std::tan(tilt), k * dz};
    s.instance = k + 1;
    for (unsigned j = 0; j < s.rows; ++j)
      for (unsigned i = 0; i < s.cols; ++i)
        s.stored.push_back(ms::testing::stored_for(s, field(s.ipp + Vec3{i * s.spacing_i, j * s.spacing_j, 0})));
    ms::testing::write_slice((dir / ("t" + std::to_string(k) + ".dcm")).string(), s);
  }
  const auto s = io::read_scan(dir.string());
  EXPECT_TRUE(has_warning(s, "tilt of 15.0"));
  // Orthogonal grid: direction is orthonormal, z spacing is the true slice spacing.
  EXPECT_NEAR(s.volume.geom.spacing[2], dz, 1e-6);
  EXPECT_GT(s.volume.geom.size[1], base.rows);  // widened to cover the sheared stack
  expect_field(s.volume, 0.6, /*skip_air=*/true);
  fs::remove_all(dir);
}

TEST(Ingest, OneMissingSliceIsInterpolatedWithAWarning) {
  const fs::path dir = temp_dir("missing1");
  ms::testing::write_series(dir.string(), SliceSpec{}, 12, 0.0, 1.25, field);
  fs::remove(dir / "s_005.dcm");
  const auto s = io::read_scan(dir.string());
  EXPECT_TRUE(has_warning(s, "missing slice"));
  EXPECT_EQ(s.volume.geom.size[2], 12u);  // back on the uniform grid
  expect_field(s.volume, 0.6);
  fs::remove_all(dir);
}

TEST(Ingest, ExactDuplicateSlicesAreDropped) {
  const fs::path dir = temp_dir("dups");
  ms::testing::write_series(dir.string(), SliceSpec{}, 10, 0.0, 1.0, field);
  fs::copy_file(dir / "s_004.dcm", dir / "copy_of_4.dcm");
  const auto s = io::read_scan(dir.string());
  EXPECT_TRUE(has_warning(s, "duplicate"));
  EXPECT_EQ(s.volume.geom.size[2], 10u);
  expect_field(s.volume, 0.51);
  fs::remove_all(dir);
}

TEST(Ingest, SlicesStoredTopDownWithShuffledInstanceNumbersComeOutInPositionOrder) {
  const fs::path dir = temp_dir("order");
  SliceSpec base;
  auto specs = ms::testing::write_series(dir.string(), base, 10, 30.0, -2.0, field);  // descending z
  // Rewrite with scrambled InstanceNumbers.
  for (std::size_t k = 0; k < specs.size(); ++k) {
    specs[k].instance = static_cast<int>((k * 7) % 10) + 1;
    ms::testing::write_slice((dir / ("x" + std::to_string(k) + ".dcm")).string(), specs[k]);
  }
  for (int k = 0; k < 10; ++k) {
    char n[32];
    std::snprintf(n, sizeof n, "s_%03d.dcm", k);
    fs::remove(dir / n);
  }
  const auto s = io::read_scan(dir.string());
  EXPECT_NEAR(s.volume.geom.origin[2], 12.0, 1e-6);  // lowest slice first
  EXPECT_NEAR(s.volume.geom.direction[8], 1.0, 1e-9);
  expect_field(s.volume, 0.51);
  fs::remove_all(dir);
}

TEST(Ingest, RescaleIsAppliedPerSlice) {
  const fs::path dir = temp_dir("rescale");
  for (int k = 0; k < 10; ++k) {
    SliceSpec s;
    s.ipp = {0, 0, 1.0 * k};
    s.slope = k % 2 ? 0.5 : 1.0;
    s.intercept = k % 2 ? -1000.0 : -1024.0;
    for (unsigned j = 0; j < s.rows; ++j)
      for (unsigned i = 0; i < s.cols; ++i)
        s.stored.push_back(ms::testing::stored_for(s, field(s.ipp + Vec3{i * s.spacing_i, j * s.spacing_j, 0})));
    ms::testing::write_slice((dir / ("r" + std::to_string(k) + ".dcm")).string(), s);
  }
  expect_field(io::read_scan(dir.string()).volume, 0.51);
  fs::remove_all(dir);
}

TEST(Ingest, Monochrome1DoesNotChangeHu) {
  const fs::path dir = temp_dir("mono1");
  SliceSpec base;
  base.photometric = "MONOCHROME1";
  ms::testing::write_series(dir.string(), base, 9, 0.0, 1.0, field);
  const auto s = io::read_scan(dir.string());
  EXPECT_TRUE(has_warning(s, "MONOCHROME1"));
  expect_field(s.volume, 0.51);
  fs::remove_all(dir);
}

TEST(Ingest, PaddingAndValuesBelowAirBecomeAir) {
  const fs::path dir = temp_dir("padding");
  SliceSpec base;
  base.signed_pixels = true;
  base.intercept = 0;
  base.padding = -2000;
  auto specs = ms::testing::write_series(dir.string(), base, 9, 0.0, 1.0, [](const Vec3&) { return 40.0; });
  // Corner pixels carry the padding value, one pixel is -3024 HU (outside the FOV circle).
  for (std::size_t k = 0; k < specs.size(); ++k) {
    specs[k].stored[0] = -2000;
    specs[k].stored[1] = -3024;
    char n[32];
    std::snprintf(n, sizeof n, "s_%03zu.dcm", k);
    ms::testing::write_slice((dir / n).string(), specs[k]);
  }
  const auto s = io::read_scan(dir.string());
  EXPECT_TRUE(has_warning(s, "padding"));
  EXPECT_FLOAT_EQ(s.volume.hu[0], -1024.0f);
  EXPECT_FLOAT_EQ(s.volume.hu[1], -1024.0f);
  EXPECT_FLOAT_EQ(s.volume.hu[2], 40.0f);
  fs::remove_all(dir);
}

TEST(Ingest, BitsAboveBitsStoredAreIgnoredAndSignedPixelsWork) {
  const fs::path dir = temp_dir("bits");
  SliceSpec u;
  u.bits_stored = 12;
  auto specs = ms::testing::write_series(dir.string(), u, 9, 0.0, 1.0, field, "u");
  for (std::size_t k = 0; k < specs.size(); ++k) {
    for (auto& v : specs[k].stored) v |= 0xB000;  // overlay garbage in the top 4 bits
    char n[32];
    std::snprintf(n, sizeof n, "u_%03zu.dcm", k);
    ms::testing::write_slice((dir / n).string(), specs[k]);
  }
  expect_field(io::read_scan(dir.string()).volume, 0.51);
  fs::remove_all(dir);
  const fs::path dir2 = temp_dir("signed");
  SliceSpec sg;
  sg.signed_pixels = true;
  sg.intercept = 0;
  ms::testing::write_series(dir2.string(), sg, 9, -300.0, 1.0, field);  // negative HU stored as negatives
  expect_field(io::read_scan(dir2.string()).volume, 0.51);
  fs::remove_all(dir2);
  // Signed 12 bits in 16 with overlay bits above: the sign comes from bit 11.
  const fs::path dir3 = temp_dir("signed12");
  SliceSpec s12 = sg;
  s12.bits_stored = 12;
  auto specs12 = ms::testing::write_series(dir3.string(), s12, 9, -300.0, 1.0, field, "s");
  bool negative = false;
  for (std::size_t k = 0; k < specs12.size(); ++k) {
    for (auto& v : specs12[k].stored) {
      negative = negative || v < 0;
      v = (v & 0x0FFF) | 0xA000;
    }
    char n[32];
    std::snprintf(n, sizeof n, "s_%03zu.dcm", k);
    ms::testing::write_slice((dir3 / n).string(), specs12[k]);
  }
  ASSERT_TRUE(negative);
  expect_field(io::read_scan(dir3.string()).volume, 0.51);
  fs::remove_all(dir3);
}

TEST(Ingest, MixedStudyChoosesTheFinestCtCoveringTheHead) {
  const fs::path dir = temp_dir("mixed");
  SliceSpec fine, coarse, mr, loc;
  fine.series_uid = "1.2.3.100";
  coarse.series_uid = "1.2.3.200";
  coarse.spacing_i = coarse.spacing_j = 1.8;
  mr.series_uid = "1.2.3.300";
  mr.modality = "MR";
  mr.sop_class = "1.2.840.10008.5.1.4.1.1.4";
  loc.series_uid = "1.2.3.400";
  loc.image_type = "ORIGINAL\\PRIMARY\\LOCALIZER";
  ms::testing::write_series((dir / "a").string(), coarse, 10, 0.0, 3.0, field, "coarse");
  ms::testing::write_series((dir / "b" / "c").string(), fine, 28, 0.0, 1.0, field, "fine");
  ms::testing::write_series((dir / "a").string(), mr, 30, 0.0, 1.0, field, "mr");
  ms::testing::write_series(dir.string(), loc, 12, 0.0, 2.5, field, "loc");
  std::ofstream(dir / "README.txt") << "not DICOM";
  const auto sc = io::dicom::scan(dir.string());
  EXPECT_EQ(sc.series.size(), 4u);
  EXPECT_EQ(sc.files_seen, 81u);
  EXPECT_EQ(sc.dicom_files, 80u);
  const auto s = io::read_scan(dir.string());
  EXPECT_EQ(s.info.series_uid, "1.2.3.100");
  EXPECT_EQ(s.volume.geom.size[2], 28u);
  // --series overrides the rule.
  io::ReadOptions ro;
  ro.series_uid = "1.2.3.200";
  EXPECT_NEAR(io::read_scan(dir.string(), ro).volume.geom.spacing[0], 1.8, 1e-9);
  fs::remove_all(dir);
}

TEST(Ingest, OneUidWithTwoOrientationsIsSplitIntoStacks) {
  const fs::path dir = temp_dir("stacks");
  SliceSpec axial, coronal;
  coronal.row_dir = {1, 0, 0};
  coronal.col_dir = {0, 0, -1};
  ms::testing::write_series(dir.string(), axial, 20, 0.0, 1.0, field, "ax");
  ms::testing::write_series(dir.string(), coronal, 9, 0.0, 2.0, field, "cor");
  const auto sc = io::dicom::scan(dir.string());
  ASSERT_EQ(sc.series.size(), 2u);
  EXPECT_NE(sc.series[0].label.find('#'), std::string::npos);
  const auto s = io::read_scan(dir.string());
  EXPECT_EQ(s.volume.geom.size[2], 20u);
  EXPECT_NEAR(s.volume.geom.direction[8], 1.0, 1e-9);
  expect_field(s.volume, 0.51);
  fs::remove_all(dir);
}

TEST(Ingest, VolumeFilesHonourOrientationOverride) {
  const fs::path dir = temp_dir("orient");
  ms::testing::write_series(dir.string(), SliceSpec{}, 9, 0.0, 1.0, field);
  const auto dcm = io::read_scan(dir.string());
  Mask m;
  m.geom = dcm.volume.geom;
  m.data.assign(m.geom.voxel_count(), 1);
  io::write_mask(m, (dir / "v.nii.gz").string());
  io::ReadOptions ro;
  ro.orientation = "LAI";
  const auto v = io::read_scan((dir / "v.nii.gz").string(), ro);
  // The file's axes as the code says: i -> L, j -> A, k -> I; ingest then
  // brings the grid to the canonical array order (core/array_order.h): the
  // same voxel positions with j and k reversed, direction = identity.
  ms::Geometry as_coded = dcm.volume.geom;
  as_coded.direction = {1, 0, 0, 0, -1, 0, 0, 0, -1};
  const ms::Geometry expected = ms::reordered(as_coded, ms::canonical_reorder(as_coded));
  EXPECT_TRUE(v.volume.geom.same_grid(expected, 1e-6));
  for (int a = 0; a < 9; ++a) EXPECT_NEAR(v.volume.geom.direction[a], a % 4 == 0 ? 1.0 : 0.0, 1e-12);
  EXPECT_NEAR(expected.origin[1], as_coded.index_to_lps(0, double(as_coded.size[1] - 1), 0)[1], 1e-9);
  ro.orientation = "LLS";
  EXPECT_THROW(io::read_scan((dir / "v.nii.gz").string(), ro), Error);
  fs::remove_all(dir);
}

// A header can declare far more voxels than its file holds; ITK would
// allocate all of them before reading one (found by fuzzing: terabytes from a
// 200-byte NRRD). Refused with InputInvalid before any allocation, for
// attached and detached headers, volumes and masks; a genuine gzip NRRD of a
// constant volume (compressing ~200:1) still loads.
TEST(Ingest, HeadersDeclaringMoreThanTheFileHoldsAreRefusedBeforeAllocating) {
  const fs::path dir = temp_dir("declared");
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name, std::ios::binary) << text;
    return (dir / name).string();
  };
  const std::string nrrd = write("big.nrrd",
                                 "NRRD0004\ndimension: 3\nsizes: 100000 100000 100000\ntype: short\nendian: little\n"
                                 "encoding: raw\n\n0123456789");
  const std::string mha = write("big.mha",
                                "ObjectType = Image\nNDims = 3\nDimSize = 4000 4000 4000\nElementType = MET_FLOAT\n"
                                "ElementDataFile = LOCAL\n0123456789");
  write("small.raw", std::string(2048, '\0'));
  const std::string nhdr = write("detached.nhdr",
                                 "NRRD0004\ndimension: 3\nsizes: 2000 2000 500\ntype: short\nendian: little\n"
                                 "encoding: gzip\ndata file: small.raw\n");
  for (const std::string& f : {nrrd, mha, nhdr}) {
    for (int which = 0; which < 2; ++which) {
      try {
        if (which == 0) io::read_scan(f);
        else io::read_label_map(f);
        ADD_FAILURE() << f << " accepted";
      } catch (const Error& e) {
        EXPECT_EQ(e.code(), ExitCode::InputInvalid) << e.what();
        EXPECT_NE(std::string(e.what()).find("declares"), std::string::npos) << e.what();
      }
    }
  }
  Volume v;
  v.geom.size = {200, 200, 100};
  v.hu.assign(v.geom.voxel_count(), -1000.0f);
  io::write_volume(v, (dir / "constant.nrrd").string());
  EXPECT_LT(fs::file_size(dir / "constant.nrrd"), 160000u);  // 16 MB of floats compressed > 100:1
  EXPECT_EQ(io::read_scan((dir / "constant.nrrd").string()).volume.hu.size(), v.hu.size());
  fs::remove_all(dir);
}

TEST(Ingest, HeadsqNrrdFromSharedDataLoads) {
  const std::string path = std::string(MANDISYM_SHARED_DATA) + "/headsq/quarter.nhdr";
  if (!fs::exists(path)) GTEST_SKIP() << "shared data not present";
  io::ReadOptions ro;
  ro.hu_offset = -1024;
  const auto s = io::read_scan(path, ro);
  EXPECT_EQ(s.volume.geom.size[0], 64u);
  EXPECT_EQ(s.volume.geom.size[2], 93u);
  EXPECT_NEAR(s.volume.geom.spacing[0], 3.2, 1e-6);
  EXPECT_NEAR(s.volume.geom.spacing[2], 1.5, 1e-6);
  EXPECT_TRUE(has_warning(s, "not anatomical"));
  float mn = 1e9f;
  for (float v : s.volume.hu) mn = std::min(mn, v);
  EXPECT_LT(mn, -900.0f);  // air after the offset
}

namespace {

// The structure check that keeps malformed files away from GDCM (which
// asserts, or allocates whatever a length declares): real files in every
// transfer syntax pass; each defect found by fuzzing fails.
TEST(Ingest, SafeToParseRejectsWhatGdcmCannotTake) {
  using ms::testing::element;
  const fs::path dir = fs::temp_directory_path() / ("mandisym_safe_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  auto write = [&](const std::string& name, const std::string& bytes) {
    const fs::path p = dir / name;
    std::ofstream(p, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return p.string();
  };
  ms::testing::SliceSpec s;
  s.rows = 6;
  s.cols = 7;
  for (const char* ts : {"raw", "implicit", "jpeg-lossless", "jpeg2000", "rle"}) {
    s.transfer_syntax = ts;
    const std::string p = (dir / (std::string(ts) + ".dcm")).string();
    ms::testing::write_slice(p, s);
    EXPECT_TRUE(ms::io::dicom::safe_to_parse(p)) << ts;
  }
  ms::testing::EnhancedSpec e;
  e.base = s;
  e.base.transfer_syntax = "raw";
  e.ipps = {{0, 0, 0}, {0, 0, 1}};
  e.frames.assign(2, std::vector<std::int32_t>(42, 1000));
  ms::testing::write_enhanced((dir / "enhanced.dcm").string(), e);
  EXPECT_TRUE(ms::io::dicom::safe_to_parse((dir / "enhanced.dcm").string())) << "nested sequences";

  const std::string meta = ms::testing::preamble() + element(0x0002, 0x0010, "UI", std::string("1.2.840.10008.1.2.1\0", 20));
  const std::string good = meta + element(0x0008, 0x0060, "CS", "CT") + element(0x0009, 0x1010, "OB", std::string(64, 'x'));
  EXPECT_TRUE(ms::io::dicom::safe_to_parse(write("good.dcm", good)));
  // A declared length past the end of the file.
  EXPECT_FALSE(ms::io::dicom::safe_to_parse(
      write("long.dcm", meta + element(0x0008, 0x0060, "CS", "CT") + element(0x0009, 0x1010, "OB", std::string(64, 'x'), 0xff000000u))));
  // A file meta element with a VR GDCM does not know (found by fuzzing).
  EXPECT_FALSE(ms::io::dicom::safe_to_parse(write(
      "badvr.dcm", ms::testing::preamble() + element(0x0002, 0x0002, "UK", std::string("1.2.840.10008.5.1.4.1.1.2\0", 26)) +
                       element(0x0002, 0x0010, "UI", std::string("1.2.840.10008.1.2.1\0", 20)) + element(0x0008, 0x0060, "CS", "CT"))));
  // The file meta group cut inside an element, at every byte.
  for (std::size_t cut = 133; cut < meta.size(); ++cut)
    EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("cut.dcm", meta.substr(0, cut)))) << cut;
  // The data set cut inside its last element's header (tag read, VR or
  // 16-bit length missing: GDCM asserted, found by fuzzing); a clean end is fine.
  const std::string body = meta + element(0x0008, 0x0060, "CS", "CT") + element(0x0008, 0x0070, "LO", "ACME");
  EXPECT_TRUE(ms::io::dicom::safe_to_parse(write("whole.dcm", body)));
  for (std::size_t keep = 4; keep < 8; ++keep)
    EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("cuthdr.dcm", body.substr(0, body.size() - 12 + keep)))) << keep;
  // An undefined length on an element that is neither a sequence nor UN
  // (found by fuzzing: GDCM asserts).
  EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("undef.dcm", meta + element(0x0008, 0x0060, "CS", "CT") +
                                                                     element(0x0009, 0x1010, "OB", "", 0xffffffffu))));
  // An item whose content (an undefined-length sequence) runs past its
  // declared length (found by fuzzing: GDCM's fallback reader asserts).
  {
    const std::string inner = element(0x0020, 0x9116, "SQ", "", 0xffffffffu) + std::string("\xfe\xff\x00\xe0\xff\xff\xff\xff", 8) +
                              element(0x0020, 0x0037, "DS", "1\\0\\0\\0\\1\\0 ") + std::string("\xfe\xff\x0d\xe0\0\0\0\0", 8) +
                              std::string("\xfe\xff\xdd\xe0\0\0\0\0", 8);
    std::string item = std::string("\xfe\xff\x00\xe0", 4) + std::string("\x15\0\0\0", 4) + inner;  // declares 21 bytes
    const std::string seq = element(0x5200, 0x9229, "SQ", "", 0xffffffffu) + item + std::string("\xfe\xff\xdd\xe0\0\0\0\0", 8);
    EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("overrun.dcm", meta + element(0x0008, 0x0060, "CS", "CT") + seq)));
    // The same item with its true length is fine.
    item = std::string("\xfe\xff\x00\xe0", 4) + std::string(1, static_cast<char>(inner.size())) + std::string("\0\0\0", 3) + inner;
    EXPECT_TRUE(ms::io::dicom::safe_to_parse(write("fits.dcm", meta + element(0x0008, 0x0060, "CS", "CT") +
                                                                   element(0x5200, 0x9229, "SQ", "", 0xffffffffu) + item +
                                                                   std::string("\xfe\xff\xdd\xe0\0\0\0\0", 8))));
  }
  // Deflated explicit VR little endian: the data set is inflated and walked
  // (found by fuzzing: GDCM asserted on a deflate stream of junk).
  {
    auto deflate_raw = [](const std::string& in) {
      z_stream z{};
      deflateInit2(&z, Z_BEST_COMPRESSION, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY);
      std::string out(in.size() + 256, '\0');
      z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
      z.avail_in = static_cast<uInt>(in.size());
      z.next_out = reinterpret_cast<Bytef*>(out.data());
      z.avail_out = static_cast<uInt>(out.size());
      deflate(&z, Z_FINISH);
      out.resize(z.total_out);
      deflateEnd(&z);
      return out;
    };
    const std::string dmeta = ms::testing::preamble() + element(0x0002, 0x0010, "UI", std::string("1.2.840.10008.1.2.1.99", 22));
    const std::string data = element(0x0008, 0x0060, "CS", "CT") + element(0x0009, 0x1010, "OB", std::string(64, 'x'));
    EXPECT_TRUE(ms::io::dicom::safe_to_parse(write("deflated.dcm", dmeta + deflate_raw(data))));
    std::string long_ob = data;
    long_ob[long_ob.size() - 64 - 2] = '\x7f';  // the OB now declares ~2 GB
    EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("deflated_long.dcm", dmeta + deflate_raw(long_ob))));
    EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("deflated_junk.dcm", dmeta + "\x01\x02\x03 not a deflate stream")));
  }
  // A sequence delimiter in the other byte order (found by fuzzing: GDCM's
  // workaround then read a 3.6 GB length from a 1 kB file).
  EXPECT_FALSE(ms::io::dicom::safe_to_parse(write(
      "swapped.dcm", meta + element(0x0008, 0x0060, "CS", "CT") + element(0x5200, 0x9229, "SQ", "", 0xffffffffu) +
                         std::string("\xfe\xff\x00\xe0\xff\xff\xff\xff", 8) + element(0x0020, 0x0037, "DS", "1\\0\\0\\0\\1\\0 ") +
                         std::string("\xfe\xff\x0d\xe0\0\0\0\0", 8) + std::string("\xff\xfe\xe0\xdd\0\0\0\0", 8) +
                         element(0x0028, 0x0010, "US", std::string("\x08\0", 2)))));
  // Explicit VR big endian (retired, still met): walked in its byte order.
  {
    auto be = [](std::uint16_t g, std::uint16_t e, const char* vr, const std::string& v) {
      std::string x{static_cast<char>(g >> 8), static_cast<char>(g & 0xff), static_cast<char>(e >> 8), static_cast<char>(e & 0xff), vr[0], vr[1]};
      if (std::string(vr) == "OB") {
        x += std::string(2, '\0');
        for (int k = 3; k >= 0; --k) x += static_cast<char>((v.size() >> (8 * k)) & 0xff);
      } else {
        x += static_cast<char>(v.size() >> 8);
        x += static_cast<char>(v.size() & 0xff);
      }
      return x + v;
    };
    const std::string bmeta = ms::testing::preamble() + element(0x0002, 0x0010, "UI", std::string("1.2.840.10008.1.2.2\0", 20));
    const std::string bbody = bmeta + be(0x0008, 0x0060, "CS", "CT") + be(0x0009, 0x1010, "OB", std::string(64, 'x'));
    EXPECT_TRUE(ms::io::dicom::safe_to_parse(write("big.dcm", bbody)));
    EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("bigcut.dcm", bbody.substr(0, bbody.size() - 64 - 12 + 6)))) << "header cut";
    std::string bad = bbody;
    bad[bad.size() - 64 - 4] = '\x7f';  // the OB's big-endian length now ~2 GB
    EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("biglong.dcm", bad)));
    // Without preamble and meta group (ACR-NEMA style): flat data sets only;
    // a sequence sent GDCM into a vendor workaround that asserts (found by fuzzing).
    const std::string flat = be(0x0008, 0x0060, "CS", "CT") + be(0x0009, 0x1010, "OB", std::string(64, 'x'));
    EXPECT_TRUE(ms::io::dicom::safe_to_parse(write("bigflat.dcm", flat)));
    const std::string sq = std::string("\x00\x08\x11\x40SQ\0\0\xff\xff\xff\xff", 12) + std::string("\xff\xfe\xe0\x00\xff\xff\xff\xff", 8) +
                           be(0x0008, 0x1150, "UI", "1.2 ") + std::string("\xff\xfe\xe0\x0d\0\0\0\0", 8) +
                           std::string("\xff\xfe\xe0\xdd\0\0\0\0", 8);
    EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("bigseq.dcm", be(0x0008, 0x0060, "CS", "CT") + sq)));
  }
  // Two letters that are not a VR (found by fuzzing: GDCM's recovery read a
  // 1.3 GB length).
  EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("notvr.dcm", meta + element(0x0008, 0x0060, "CS", "CT") +
                                                                     element(0x0028, 0xfffb, "BS", "MONOCHROME2 "))));
  // "DICM" followed by no file meta group (found by fuzzing: GDCM guessed big endian).
  EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("nometa.dcm", ms::testing::preamble() + element(0x0101, 0x0000, "UL", std::string("\xf0\0\0\0", 4)) +
                                                                     element(0x0008, 0x0060, "CS", "CT"))));
  // A command-group element in a file (found by fuzzing: (0000,0000) without
  // a VR made GDCM re-read the file and assert).
  EXPECT_FALSE(ms::io::dicom::safe_to_parse(
      write("group0.dcm", meta + element(0x0008, 0x0060, "CS", "CT") + std::string(8, '\0') + element(0x0008, 0x0070, "LO", "ACME"))));
  // A sequence delimiter where an element belongs.
  EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("delim.dcm", meta + element(0x0008, 0x0060, "CS", "CT") +
                                                                     std::string("\xfe\xff\xdd\xe0\0\0\0\0", 8))));
  // No preamble: a data set may start with group 0008, arbitrary bytes may not.
  EXPECT_TRUE(ms::io::dicom::safe_to_parse(write("bare.dcm", element(0x0008, 0x0060, "CS", "CT") + element(0x0008, 0x0070, "LO", "ACME SCANNERS"))));
  EXPECT_FALSE(ms::io::dicom::safe_to_parse(write("junk.dcm", std::string("%PDF-1.4 not a scan at all"))));
  fs::remove_all(dir);
}

}  // namespace
