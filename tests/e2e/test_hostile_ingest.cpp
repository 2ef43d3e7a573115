// End to end: hostile inputs (a security/robustness report against ingest)
// are refused cleanly by the real binary, before they can crash a later stage,
// change the answer silently, hang, read files outside the input or allocate
// gigabytes. Same contract as test_bad_input.cpp (README.md, "Exit codes"):
//   1. exit code 4 (invalid input), or 3 (not found / unreadable);
//   2. stderr is exactly one line, starting "mandisym: error: ", naming the
//      offending file (the slice, the header or the data file);
//   3. no crash: death by a signal or exit code 1 fails;
//   4. OUTDIR holds no results.json and no report.html afterwards.
// Memory bombs run the binary under RLIMIT_AS (kBombAddressSpace) and check
// its peak RSS (wait4): they pass because the refusal comes before any
// allocation, never by using gigabytes. Every case also stays within the
// hostile-input corpus budget (2 GB, 60 s; tests/support/binary_run.h).
// Policies and limits: docs/ingest.md.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <zlib.h>

#include <gdcmDataSet.h>
#include <gdcmReader.h>
#include <gdcmWriter.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/memory.h"
#include "io/volume_io.h"
#include "tests/support/binary_run.h"
#include "tests/support/dicom_forge.h"

namespace fs = std::filesystem;
using ms::Vec3;
using ms::testing::SliceSpec;

namespace {

using ms::testing::expect_refused;
using ms::testing::RunLimits;
using ms::testing::RunResult;

// Address space the binary gets in the memory-bomb cases: enough to start
// (it reserves 1.5 GB of heap address space, untouched) and far below what
// the bombs would allocate. The default budget follows it (RLIMIT_AS).
constexpr rlim_t kBombAddressSpace = rlim_t{3} << 30;
// Peak RSS a refused bomb may reach: the binary itself, ITK and GDCM (~100 MB).
constexpr long kRefusedPeakRssKbPlain = 300 * 1024;
// Under AddressSanitizer (scripts/test sets MANDISYM_SANITIZED=1) the same
// refusal peaks at ~360 MB (shadow memory, quarantine, redzones): still a
// fraction of the gigabytes a bomb took before its fix.
constexpr long kRefusedPeakRssKbSanitized = 1024 * 1024;
const long kRefusedPeakRssKb = std::getenv("MANDISYM_SANITIZED") ? kRefusedPeakRssKbSanitized : kRefusedPeakRssKbPlain;

struct TempCase : ms::testing::TempCase {
  TempCase() : ms::testing::TempCase("mandisym_hostile") {}
};

// `mandisym run INPUT -o OUTDIR --quiet --no-figures [extra]` through the
// shared runner (tests/support/binary_run.h; its 60 s guard kills a
// regression that blocks on a FIFO); address_space > 0 sets RLIMIT_AS.
RunResult run_on(const fs::path& input, const fs::path& out, const std::vector<std::string>& extra = {},
                 rlim_t address_space = 0) {
  std::vector<std::string> args{"run", input.string(), "-o", out.string(), "--quiet", "--no-figures"};
  args.insert(args.end(), extra.begin(), extra.end());
  RunLimits limits;
  limits.address_space = address_space;
  return ms::testing::run_binary(args, out, limits);
}

// ---------------------------------------------------------------- DICOM helpers

double water_cylinder(const Vec3& p) { return (p[0] - 10) * (p[0] - 10) + (p[1] - 9) * (p[1] - 9) < 64 ? 0.0 : -1000.0; }

SliceSpec ct_base() {
  SliceSpec s;
  s.series_uid = "1.2.826.0.1.3680043.10.1.77";
  return s;
}

std::vector<SliceSpec> good_series(const fs::path& dir, SliceSpec base = ct_base(), int n = 12) {
  return ms::testing::write_series(dir.string(), base, n, 0.0, 1.0, water_cylinder);
}

std::string slice_name(const fs::path& dir, int k) {
  std::ostringstream n;
  n << "s_" << std::setw(3) << std::setfill('0') << k << ".dcm";
  return (dir / n.str()).string();
}

// Rewrites one DICOM file after `edit` changed its data set (GDCM).
void edit_dicom(const std::string& file, const std::function<void(gdcm::DataSet&)>& edit) {
  gdcm::Reader r;
  r.SetFileName(file.c_str());
  ASSERT_TRUE(r.Read()) << file;
  edit(r.GetFile().GetDataSet());
  gdcm::Writer w;
  w.SetFile(r.GetFile());
  w.SetFileName(file.c_str());
  ASSERT_TRUE(w.Write()) << file;
}

void set_value(gdcm::DataSet& ds, std::uint16_t g, std::uint16_t e, gdcm::VR vr, std::string value) {
  if (value.size() % 2) value += vr == gdcm::VR::UI ? '\0' : ' ';
  gdcm::DataElement de(gdcm::Tag(g, e));
  de.SetVR(vr);
  de.SetByteValue(value.data(), static_cast<std::uint32_t>(value.size()));
  ds.Replace(de);
}

void set_us(gdcm::DataSet& ds, std::uint16_t g, std::uint16_t e, std::uint16_t v) {
  set_value(ds, g, e, gdcm::VR::US, std::string(reinterpret_cast<const char*>(&v), 2));
}

// ---------------------------------------------------------------- volume helpers

// NIfTI-1 header (348 bytes + 4 extension bytes), float32 data at 352, both
// orientation codes 0 unless a test sets them.
struct NiftiHeader {
  unsigned char h[352] = {};
  NiftiHeader(const std::vector<int>& dims, std::int16_t datatype = 16, std::int16_t bitpix = 32) {
    i32(0, 348);
    i16(40, static_cast<std::int16_t>(dims.size()));
    for (int a = 0; a < 7; ++a) i16(42 + 2 * a, a < static_cast<int>(dims.size()) ? static_cast<std::int16_t>(dims[a]) : 1);
    i16(70, datatype);
    i16(72, bitpix);
    for (int a = 0; a < 8; ++a) f32(76 + 4 * a, 1.0f);
    f32(108, 352.0f);
    f32(112, 1.0f);
    h[123] = 2;
    std::memcpy(h + 344, "n+1\0", 4);
  }
  void i32(int off, std::int32_t v) { std::memcpy(h + off, &v, 4); }
  void i16(int off, std::int16_t v) { std::memcpy(h + off, &v, 2); }
  void f32(int off, float v) { std::memcpy(h + off, &v, 4); }
  // sform rows (RAS) with code 1.
  void sform(const float (&rows)[12]) {
    i16(254, 1);
    for (int k = 0; k < 12; ++k) f32(280 + 4 * k, rows[k]);
  }
  // qform: identity rotation (quaternion 0), origin o, code 1.
  void qform_identity(float ox, float oy, float oz) {
    i16(252, 1);
    f32(268, ox), f32(272, oy), f32(276, oz);
  }
  void write(const fs::path& p, std::size_t data_bytes, char fill = 0) const {
    std::ofstream f(p, std::ios::binary);
    f.write(reinterpret_cast<const char*>(h), sizeof h);
    const std::string block(1 << 16, fill);
    for (std::size_t left = data_bytes; left > 0;) {
      const std::size_t n = std::min(left, block.size());
      f.write(block.data(), static_cast<std::streamsize>(n));
      left -= n;
    }
  }
};

// A head-like float32 payload: air with water every third voxel.
std::string head_like_payload(std::size_t voxels) {
  std::string s(voxels * 4, '\0');
  for (std::size_t i = 0; i < voxels; ++i) {
    const float v = i % 3 ? -1000.0f : 40.0f;
    std::memcpy(&s[i * 4], &v, 4);
  }
  return s;
}

void write_text(const fs::path& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }

// `bytes` zero bytes deflated (zlib format when gzip is false), streamed.
std::string deflate_zeros(std::uint64_t bytes, bool gzip) {
  z_stream z{};
  deflateInit2(&z, 9, Z_DEFLATED, gzip ? 15 + 16 : 15, 9, Z_DEFAULT_STRATEGY);
  const std::string zeros(1 << 20, '\0');
  std::string out;
  std::vector<unsigned char> buf(1 << 16);
  for (std::uint64_t left = bytes;;) {
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(left, zeros.size()));
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(zeros.data()));
    z.avail_in = static_cast<uInt>(n);
    left -= n;
    const int flush = left ? Z_NO_FLUSH : Z_FINISH;
    int rc;
    do {
      z.next_out = buf.data();
      z.avail_out = static_cast<uInt>(buf.size());
      rc = deflate(&z, flush);
      out.append(reinterpret_cast<char*>(buf.data()), buf.size() - z.avail_out);
    } while (z.avail_out == 0);
    if (rc == Z_STREAM_END || (!left && flush == Z_FINISH && rc == Z_STREAM_END)) break;
  }
  deflateEnd(&z);
  return out;
}

// `bytes` of pseudo-random data (barely compressible) as one zlib stream.
std::string zlib_noise(std::size_t bytes) {
  std::string raw(bytes, '\0');
  std::uint32_t x = 2463534242u;
  for (auto& c : raw) {
    x ^= x << 13, x ^= x >> 17, x ^= x << 5;
    c = static_cast<char>(x & 0xff);
  }
  uLongf n = compressBound(static_cast<uLong>(bytes));
  std::string out(n, '\0');
  compress2(reinterpret_cast<Bytef*>(out.data()), &n, reinterpret_cast<const Bytef*>(raw.data()), static_cast<uLong>(bytes), 6);
  out.resize(n);
  return out;
}

}  // namespace

// ---------------------------------------------------------------- 1. geometry

// An ImagePositionPatient x of 1e300 mm went through ingest and ended in
// SIGFPE in CGAL (gmpq_set_d on a non-finite value).
TEST(HostileIngest, DicomPositionBeyondTenMetres) {
  TempCase t;
  const fs::path in = t / "ct";
  good_series(in);
  const std::string bad = slice_name(in, 6);
  edit_dicom(bad, [](gdcm::DataSet& ds) { set_value(ds, 0x0020, 0x0032, gdcm::VR::DS, "1e300\\0\\6"); });
  expect_refused(run_on(in, t.out()), 4, t.out(), {bad, "ImagePositionPatient", "10 m"});
  edit_dicom(bad, [](gdcm::DataSet& ds) { set_value(ds, 0x0020, 0x0032, gdcm::VR::DS, "nan\\0\\6"); });
  expect_refused(run_on(in, t.out()), 4, t.out(), {bad, "ImagePositionPatient"});
}

// PixelSpacing 1e30 mm read as "no bone" (exit 5).
TEST(HostileIngest, DicomAbsurdPixelSpacing) {
  TempCase t;
  const fs::path in = t / "ct";
  SliceSpec base = ct_base();
  base.spacing_i = base.spacing_j = 1e30;
  good_series(in, base);
  expect_refused(run_on(in, t.out()), 4, t.out(), {in.string(), ".dcm", "PixelSpacing"});
}

TEST(HostileIngest, DicomOrientationNonFiniteOrDegenerate) {
  TempCase t;
  const fs::path in = t / "ct";
  good_series(in);
  // On every slice: one odd slice alone forms its own (unusable) sub-stack
  // and the other eleven are read.
  for (const char* iop : {"1\\0\\0\\0\\inf\\0", "1\\0\\0\\0\\0\\0"}) {
    for (int k = 0; k < 12; ++k)
      edit_dicom(slice_name(in, k), [&](gdcm::DataSet& ds) { set_value(ds, 0x0020, 0x0037, gdcm::VR::DS, iop); });
    expect_refused(run_on(in, t.out()), 4, t.out(), {in.string(), ".dcm", "ImageOrientationPatient"});
  }
}

// Volume files: origin, spacing and direction must be finite and sane too.
TEST(HostileIngest, VolumeFileAbsurdGeometry) {
  TempCase t;
  const std::string payload = head_like_payload(16 * 16 * 16);
  const std::string head = "ObjectType = Image\nNDims = 3\nDimSize = 16 16 16\nElementType = MET_FLOAT\n";
  const struct {
    const char* name;
    std::string fields;
    const char* says;
  } cases[] = {
      {"far.mha", "Offset = 1e300 0 0\n", "origin"},
      {"huge_voxels.mha", "ElementSpacing = 1e30 1e30 1e30\n", "spacing"},
      {"degenerate.mha", "TransformMatrix = 1 0 0 1 0 0 0 0 1\n", "direction"},
  };
  for (const auto& c : cases) {
    const fs::path in = t / c.name;
    write_text(in, head + c.fields + "ElementDataFile = LOCAL\n" + payload);
    expect_refused(run_on(in, t.out(), {"--orientation", "LPS"}), 4, t.out(), {in.string(), c.says});
  }
  // NIfTI: an sform origin of 50 m (finite, below the 1e6 mm header limit).
  const fs::path nii = t / "far.nii";
  NiftiHeader h({16, 16, 16});
  h.sform({1, 0, 0, 5e4f, 0, 1, 0, 0, 0, 0, 1, 0});
  h.write(nii, 0);
  std::ofstream(nii, std::ios::app | std::ios::binary) << payload;
  expect_refused(run_on(nii, t.out()), 4, t.out(), {nii.string(), "origin"});
}

// ---------------------------------------------------------------- 2. rescale

// One slice without RescaleIntercept was read with intercept 0 (+1024 HU).
TEST(HostileIngest, DicomRescaleMissingOnOneSlice) {
  TempCase t;
  const fs::path in = t / "ct";
  good_series(in);
  const std::string bad = slice_name(in, 5);
  edit_dicom(bad, [](gdcm::DataSet& ds) { ds.Remove(gdcm::Tag(0x0028, 0x1052)); });
  expect_refused(run_on(in, t.out()), 4, t.out(), {bad, "RescaleIntercept"});
}

// NaN / 1e400 / 0 slope or NaN intercept: silently 1 (or 0) before.
TEST(HostileIngest, DicomRescaleNonFiniteOrZero) {
  TempCase t;
  const fs::path in = t / "ct";
  good_series(in);
  const std::string bad = slice_name(in, 8);
  const struct {
    std::uint16_t element;
    const char* value;
    const char* says;
  } cases[] = {{0x1053, "0", "RescaleSlope"}, {0x1053, "nan", "RescaleSlope"}, {0x1053, "1e400", "RescaleSlope"},
               {0x1052, "nan", "RescaleIntercept"}};
  for (const auto& c : cases) {
    edit_dicom(bad, [&](gdcm::DataSet& ds) { set_value(ds, 0x0028, c.element, gdcm::VR::DS, c.value); });
    expect_refused(run_on(in, t.out()), 4, t.out(), {bad, c.says});
    edit_dicom(bad, [&](gdcm::DataSet& ds) { set_value(ds, 0x0028, c.element, gdcm::VR::DS, c.element == 0x1053 ? "1" : "-1024"); });
  }
}

// Missing on every slice (Type 1, but seen in old exports): stored values are
// taken as HU with a warning; the run goes on (this phantom has no bone: 5).
TEST(HostileIngest, DicomRescaleMissingOnEverySliceIsAWarning) {
  TempCase t;
  const fs::path in = t / "ct";
  SliceSpec base = ct_base();
  base.intercept = 0;  // stored = HU (signed)
  base.signed_pixels = true;
  const auto specs = good_series(in, base);
  for (int k = 0; k < static_cast<int>(specs.size()); ++k)
    edit_dicom(slice_name(in, k), [](gdcm::DataSet& ds) {
      ds.Remove(gdcm::Tag(0x0028, 0x1052));
      ds.Remove(gdcm::Tag(0x0028, 0x1053));
    });
  ms::io::ReadOptions ro;
  const auto scan = ms::io::read_scan(in.string(), ro);
  bool warned = false;
  for (const auto& w : scan.info.warnings) warned |= w.find("RescaleIntercept missing from every slice") != std::string::npos;
  EXPECT_TRUE(warned);
  float mn = 1e9f;
  for (float v : scan.volume.hu) mn = std::min(mn, v);
  EXPECT_NEAR(mn, -1000.0f, 1.0f);
}

// ---------------------------------------------------------------- 3. pixel data length

// BitsAllocated 8 over 16-bit pixel data read as noise ("no bone", exit 5).
TEST(HostileIngest, DicomBitsAllocatedInconsistentWithPixelData) {
  TempCase t;
  const fs::path in = t / "ct";
  good_series(in);
  for (int k = 0; k < 12; ++k)
    edit_dicom(slice_name(in, k), [](gdcm::DataSet& ds) {
      set_us(ds, 0x0028, 0x0100, 8);
      set_us(ds, 0x0028, 0x0101, 8);
      set_us(ds, 0x0028, 0x0102, 7);
    });
  expect_refused(run_on(in, t.out()), 4, t.out(), {in.string(), ".dcm", "pixel data", "BitsAllocated"});
  // One slice only: named by its BitsAllocated.
  const fs::path in2 = t / "ct2";
  good_series(in2);
  const std::string bad = slice_name(in2, 4);
  edit_dicom(bad, [](gdcm::DataSet& ds) { set_us(ds, 0x0028, 0x0100, 8); });
  expect_refused(run_on(in2, t.out()), 4, t.out(), {bad, "BitsAllocated"});
}

// ---------------------------------------------------------------- 4. compressed frame size

// A JPEG slice whose SOF claims 60000 x 60000: 18 GB RSS, 77 s, and the error
// named another file. Now refused before decoding, naming the slice.
TEST(HostileIngest, DicomJpegFrameLargerThanRowsColumns) {
  TempCase t;
  const fs::path in = t / "ct";
  SliceSpec base = ct_base();
  base.transfer_syntax = "jpeg-lossless";
  good_series(in, base);
  const std::string bad = slice_name(in, 7);
  std::string bytes;
  {
    std::ifstream f(bad, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  }
  const auto sof = bytes.find("\xFF\xC3");
  ASSERT_NE(sof, std::string::npos);
  bytes[sof + 5] = bytes[sof + 7] = static_cast<char>(0xEA);  // 60000 = 0xEA60
  bytes[sof + 6] = bytes[sof + 8] = static_cast<char>(0x60);
  std::ofstream(bad, std::ios::binary) << bytes;
  const RunResult r = run_on(in, t.out(), {}, kBombAddressSpace);
  expect_refused(r, 4, t.out(), {bad, "60000 x 60000"});
  EXPECT_LT(r.peak_rss_kb, kRefusedPeakRssKb);
}

// ---------------------------------------------------------------- 5. NIfTI orientation

// qform and sform disagreeing on left/right: the sform won silently.
TEST(HostileIngest, NiftiQformSformDisagree) {
  TempCase t;
  const fs::path in = t / "flip.nii";
  NiftiHeader h({16, 16, 16});
  h.qform_identity(0, 0, 0);
  h.sform({-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0});  // x flipped
  h.write(in, 0);
  std::ofstream(in, std::ios::app | std::ios::binary) << head_like_payload(16 * 16 * 16);
  expect_refused(run_on(in, t.out()), 4, t.out(), {in.string(), "qform", "--orientation"});
  // --orientation settles it: ingest passes (this volume has no mandible: 5).
  const RunResult settled = run_on(in, t.out(), {"--orientation", "LPS"});
  EXPECT_TRUE(settled.exited && settled.code != 4 && settled.code != 1) << settled.err;
  // Origins 5 voxels apart.
  h.sform({1, 0, 0, 5, 0, 1, 0, 0, 0, 0, 1, 0});
  h.write(in, 0);
  std::ofstream(in, std::ios::app | std::ios::binary) << head_like_payload(16 * 16 * 16);
  expect_refused(run_on(in, t.out()), 4, t.out(), {in.string(), "origins", "--orientation"});
}

// No qform and no sform: left/right unknown, never guessed.
TEST(HostileIngest, NiftiWithoutOrientationNeedsTheOption) {
  TempCase t;
  const fs::path in = t / "uncoded.nii";
  NiftiHeader({16, 16, 16}).write(in, 0);
  std::ofstream(in, std::ios::app | std::ios::binary) << head_like_payload(16 * 16 * 16);
  expect_refused(run_on(in, t.out()), 4, t.out(), {in.string(), "--orientation"});
}

// ---------------------------------------------------------------- 6. 4D, complex, RGB, fake compression

TEST(HostileIngest, NiftiFourDimensionalComplexOrRgb) {
  TempCase t;
  const fs::path four = t / "4d.nii";
  NiftiHeader h4({16, 16, 16, 2});
  h4.sform({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0});
  h4.write(four, 0);
  std::ofstream(four, std::ios::app | std::ios::binary) << head_like_payload(16 * 16 * 16 * 2);
  expect_refused(run_on(four, t.out()), 4, t.out(), {four.string(), "volumes"});
  const struct {
    const char* name;
    std::int16_t datatype, bitpix;
    const char* says;
  } cases[] = {{"complex.nii", 32, 64, "complex64"}, {"rgb.nii", 128, 24, "RGB24"}};
  for (const auto& c : cases) {
    const fs::path in = t / c.name;
    NiftiHeader h({16, 16, 16}, c.datatype, c.bitpix);
    h.sform({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0});
    h.write(in, 16 * 16 * 16 * static_cast<std::size_t>(c.bitpix / 8), 1);
    expect_refused(run_on(in, t.out()), 4, t.out(), {in.string(), c.says});
  }
}

// CompressedData = True over raw data: read as "no bone" (5) before.
TEST(HostileIngest, MetaImageClaimingCompressionOverRawData) {
  TempCase t;
  const fs::path in = t / "fake_zlib.mha";
  write_text(in, "ObjectType = Image\nNDims = 3\nDimSize = 16 16 16\nElementType = MET_FLOAT\nCompressedData = True\n"
                 "ElementDataFile = LOCAL\n" + head_like_payload(16 * 16 * 16));
  expect_refused(run_on(in, t.out()), 4, t.out(), {in.string(), "zlib"});
}

// ---------------------------------------------------------------- 7. memory bombs

// A small .nii.gz inflating to 512^3 int16 (256 MB, so the test stays cheap):
// the header's voxels need 2.7 GB of run, over the budget under kBombAddressSpace.
// The attacker's 1.96 MB file inflating to 1000^3 is the same case, larger.
TEST(HostileIngest, GzipNiftiBombRefusedBeforeInflating) {
  TempCase t;
  const fs::path in = t / "bomb.nii.gz";
  NiftiHeader h({512, 512, 512}, 4, 16);
  h.sform({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0});
  {
    gzFile f = gzopen(in.c_str(), "wb9");
    gzwrite(f, h.h, sizeof h.h);
    const std::string zeros(1 << 20, '\0');
    for (int k = 0; k < 256; ++k) gzwrite(f, zeros.data(), static_cast<unsigned>(zeros.size()));
    gzclose(f);
  }
  const RunResult r = run_on(in, t.out(), {}, kBombAddressSpace);
  expect_refused(r, 4, t.out(), {in.string(), "--max-memory", "budget"});
  EXPECT_LT(r.peak_rss_kb, kRefusedPeakRssKb);
}

// zlib MetaImage bomb, and a zlib stream shorter than the header declares.
TEST(HostileIngest, ZlibMetaImageBombAndShortStream) {
  TempCase t;
  const fs::path bomb = t / "bomb.mha";
  write_text(bomb, "ObjectType = Image\nNDims = 3\nDimSize = 512 512 512\nElementType = MET_SHORT\nCompressedData = True\n"
                   "ElementDataFile = LOCAL\n" + deflate_zeros(std::uint64_t{256} << 20, false));
  const RunResult r = run_on(bomb, t.out(), {"--orientation", "LPS"}, kBombAddressSpace);
  expect_refused(r, 4, t.out(), {bomb.string(), "--max-memory"});
  EXPECT_LT(r.peak_rss_kb, kRefusedPeakRssKb);
  const fs::path shorter = t / "short.mha";
  write_text(shorter, "ObjectType = Image\nNDims = 3\nDimSize = 64 64 64\nElementType = MET_FLOAT\nCompressedData = True\n"
                      "ElementDataFile = LOCAL\n" + zlib_noise(64 * 64 * 32 * 4));
  expect_refused(run_on(shorter, t.out(), {"--orientation", "LPS"}), 4, t.out(), {shorter.string(), "inflates to only"});
}

// Raw data must hold the declared bytes (1x): a raw NRRD declaring
// 1500 x 1500 x 1400 over 8 MB took 6.2 GB; 200^3 over 1 MB is in budget and
// still refused, by the data check.
TEST(HostileIngest, RawNrrdDeclaringMoreThanItsDataFileHolds) {
  TempCase t;
  write_text(t / "small.raw", std::string(8 << 20, '\0'));
  const fs::path big = t / "big.nhdr";
  write_text(big, "NRRD0004\ndimension: 3\nsizes: 1500 1500 1400\ntype: short\nendian: little\nencoding: raw\ndata file: small.raw\n");
  const RunResult r = run_on(big, t.out(), {"--orientation", "LPS"}, kBombAddressSpace);
  expect_refused(r, 4, t.out(), {big.string(), "declares"});
  EXPECT_LT(r.peak_rss_kb, kRefusedPeakRssKb);
  write_text(t / "one_mb.raw", std::string(1 << 20, '\0'));
  const fs::path mid = t / "mid.nhdr";
  write_text(mid, "NRRD0004\ndimension: 3\nsizes: 200 200 200\ntype: short\nendian: little\nencoding: raw\ndata file: one_mb.raw\n");
  expect_refused(run_on(mid, t.out(), {"--orientation", "LPS"}), 4, t.out(), {mid.string(), "declares", "holds 1048576"});
}

// ---------------------------------------------------------------- 8. FIFOs and devices

TEST(HostileIngest, FifoOrDeviceAsInputOrDataFile) {
  TempCase t;
  const fs::path fifo_in = t / "pipe.nii";
  ASSERT_EQ(::mkfifo(fifo_in.c_str(), 0644), 0);
  expect_refused(run_on(fifo_in, t.out()), 4, t.out(), {fifo_in.string(), "FIFO"});
  const fs::path fifo_data = t / "data.raw";
  ASSERT_EQ(::mkfifo(fifo_data.c_str(), 0644), 0);
  const std::string head = "NRRD0004\ndimension: 3\nsizes: 16 16 16\ntype: float\nendian: little\nencoding: raw\n";
  const fs::path nhdr = t / "fifo.nhdr";
  write_text(nhdr, head + "data file: data.raw\n");
  expect_refused(run_on(nhdr, t.out(), {"--orientation", "LPS"}), 4, t.out(), {nhdr.string(), "data.raw", "FIFO"});
  // /dev/zero through a symlink in the header's folder: outside, and not a regular file.
  fs::create_symlink("/dev/zero", t / "zero.raw");
  const fs::path zero = t / "zero.nhdr";
  write_text(zero, head + "data file: zero.raw\n");
  expect_refused(run_on(zero, t.out(), {"--orientation", "LPS"}), 4, t.out(), {zero.string(), "zero.raw"});
  ms::io::ReadOptions ro;
  ro.allow_external_data_files = true;
  ro.orientation = "LPS";
  try {
    ms::io::read_scan(zero.string(), ro);
    ADD_FAILURE() << "a character device was read as data";
  } catch (const ms::Error& e) {
    EXPECT_EQ(e.code(), ms::ExitCode::InputInvalid);
    EXPECT_NE(std::string(e.what()).find("character device"), std::string::npos) << e.what();
  }
}

// A FIFO inside a DICOM folder is skipped (counted in a warning), never opened.
TEST(HostileIngest, FifoInsideDicomFolderIsSkipped) {
  TempCase t;
  const fs::path in = t / "ct";
  good_series(in);
  ASSERT_EQ(::mkfifo((in / "zz_pipe.dcm").c_str(), 0644), 0);
  const auto scan = ms::io::read_scan(in.string());
  bool warned = false;
  for (const auto& w : scan.info.warnings) warned |= w.find("not regular files") != std::string::npos;
  EXPECT_TRUE(warned);
  EXPECT_EQ(scan.volume.geom.size[2], 12u);
}

// ---------------------------------------------------------------- 9. path traversal

TEST(HostileIngest, DataFilesOutsideTheHeaderFolder) {
  TempCase t;
  fs::create_directories(t / "case" / "sub");
  write_text(t / "secret.raw", std::string(16 * 16 * 16 * 4, '\x01'));
  const std::string nrrd = "NRRD0004\ndimension: 3\nsizes: 16 16 16\ntype: float\nendian: little\nencoding: raw\n";
  const std::string meta = "ObjectType = Image\nNDims = 3\nDimSize = 16 16 16\nElementType = MET_FLOAT\n";
  const struct {
    const char* name;
    std::string text;
  } cases[] = {
      {"up.nhdr", nrrd + "data file: ../../../../../../../../etc/passwd\n"},
      {"abs.nhdr", nrrd + "data file: /etc/passwd\n"},
      {"list.nhdr", nrrd + "data file: LIST 2\nsub/../../secret.raw\n"},
      {"pattern.nhdr", nrrd + "data file: ../secre%d.raw 1 1 1 3\n"},
      {"up.mhd", meta + "ElementDataFile = ../secret.raw\n"},
      {"list.mhd", meta + "ElementDataFile = LIST\n../secret.raw\n"},
      {"pattern.mhd", meta + "ElementDataFile = ../secre%d.raw 1 1 1\n"},
  };
  for (const auto& c : cases) {
    const fs::path in = t / "case" / c.name;
    write_text(in, c.text);
    expect_refused(run_on(in, t.out(), {"--orientation", "LPS"}), 4, t.out(), {in.string(), "outside the header's folder"});
  }
  // Allowed explicitly (ReadOptions::allow_external_data_files): read.
  ms::io::ReadOptions ro;
  ro.allow_external_data_files = true;
  ro.orientation = "LPS";
  write_text(t / "case" / "ok.mhd", meta + "ElementDataFile = ../secret.raw\n");
  EXPECT_EQ(ms::io::read_scan((t / "case" / "ok.mhd").string(), ro).volume.hu.size(), 16u * 16 * 16);
  // Inside the folder, as a %d pattern (as headsq's quarter.nhdr): read.
  for (int k = 1; k <= 16; ++k) write_text(t / "case" / ("slice." + std::to_string(k)), std::string(16 * 16 * 4, '\0'));
  write_text(t / "case" / "inside.nhdr", nrrd + "data file: slice.%d 1 16 1 2\n");
  ro.allow_external_data_files = false;
  EXPECT_EQ(ms::io::read_scan((t / "case" / "inside.nhdr").string(), ro).volume.hu.size(), 16u * 16 * 16);
}

// The shipped headsq sample (data file: quarter.%d 1 93 1) still reads.
TEST(HostileIngest, HeadsqPatternStillReads) {
  const std::string path = std::string(MANDISYM_SHARED_DATA) + "/headsq/quarter.nhdr";
  if (!fs::exists(path)) GTEST_SKIP() << "shared data not present";
  ms::io::ReadOptions ro;
  ro.hu_offset = -1024;
  ro.orientation = "LPI";
  EXPECT_EQ(ms::io::read_scan(path, ro).volume.geom.size[2], 93u);
}

// ---------------------------------------------------------------- the budget itself

TEST(HostileIngest, MemorySizesParse) {
  EXPECT_EQ(ms::parse_memory_size("2G"), std::uint64_t{2} << 30);
  EXPECT_EQ(ms::parse_memory_size("512M"), std::uint64_t{512} << 20);
  EXPECT_EQ(ms::parse_memory_size("1.5GiB"), std::uint64_t{3} << 29);
  EXPECT_EQ(ms::parse_memory_size("800mb"), std::uint64_t{800} << 20);
  EXPECT_EQ(ms::parse_memory_size("300000000"), 300000000u);
  for (const char* bad : {"", "G", "-1G", "2X", "0", "1e30G", "2 G"}) {
    try {
      ms::parse_memory_size(bad);
      ADD_FAILURE() << "'" << bad << "' accepted";
    } catch (const ms::Error& e) {
      EXPECT_EQ(e.code(), ms::ExitCode::Usage);
    }
  }
  EXPECT_GT(ms::default_memory_budget_bytes(), 0u);
  EXPECT_LE(ms::default_memory_budget_bytes(), ms::machine_memory_bytes());
}

// ReadOptions::max_memory_bytes is the budget (what --max-memory sets): a
// 64^3 volume needs 5.2 MB of run; 1 MB refuses it, the default reads it.
TEST(HostileIngest, ExplicitBudgetApplies) {
  TempCase t;
  const fs::path in = t / "v.nii";
  NiftiHeader h({64, 64, 64});
  h.sform({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0});
  h.write(in, 0);
  std::ofstream(in, std::ios::app | std::ios::binary) << head_like_payload(64 * 64 * 64);
  ms::io::ReadOptions ro;
  EXPECT_EQ(ms::io::read_scan(in.string(), ro).volume.hu.size(), 64u * 64 * 64);
  ro.max_memory_bytes = 1 << 20;
  try {
    ms::io::read_scan(in.string(), ro);
    ADD_FAILURE() << "read within a 1 MB budget";
  } catch (const ms::Error& e) {
    EXPECT_EQ(e.code(), ms::ExitCode::InputInvalid);
    EXPECT_NE(std::string(e.what()).find("--max-memory"), std::string::npos) << e.what();
  }
}
