#include "io/volume_checks.h"

#include <sys/stat.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/memory.h"

namespace fs = std::filesystem;

namespace ms::io::checks {
namespace {

// Header lines scanned for the data-file field (NRRD and MetaImage headers
// are a few dozen lines; a LIST of one file per slice is the longest).
constexpr int kMaxHeaderLines = kMaxDataFiles + 200;
// NIfTI qform and sform must agree to this (docs/ingest.md, "NIfTI orientation").
constexpr double kMaxAxisDisagreementDeg = 1.0;

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r' || s.back() == '\0')) s.pop_back();
  std::size_t b = 0;
  while (b < s.size() && (s[b] == ' ' || s[b] == '\t')) ++b;
  return s.substr(b);
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::vector<std::string> words(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> w;
  for (std::string t; in >> t;) w.push_back(t);
  return w;
}

[[noreturn]] void invalid(const std::string& msg) { throw Error(ExitCode::InputInvalid, msg); }

const char* file_type(mode_t m) {
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISCHR(m)) return "a character device";
  if (S_ISBLK(m)) return "a block device";
  if (S_ISSOCK(m)) return "a socket";
  if (S_ISDIR(m)) return "a folder";
  return "not a regular file";
}

// a/b/c inside a/b (both canonical).
bool inside(const fs::path& p, const fs::path& root) {
  auto r = root.begin(), q = p.begin();
  for (; r != root.end(); ++r, ++q)
    if (q == p.end() || *q != *r) return false;
  return true;
}

// A data file named by `header`, resolved against the header's folder.
std::string resolve(const std::string& header, const std::string& name, bool allow_external) {
  std::error_code ec;
  const fs::path dir = fs::absolute(header, ec).parent_path();
  const fs::path root = fs::weakly_canonical(dir, ec);
  const fs::path real = fs::weakly_canonical(fs::path(name).is_absolute() ? fs::path(name) : dir / name, ec);
  if (ec) invalid(header + ": data file '" + name + "' cannot be resolved (" + ec.message() + ")");
  if (!allow_external && !inside(real, root))
    invalid(header + ": data file '" + name + "' resolves to " + real.string() + ", outside the header's folder " +
            root.string() + " (refused unless external data files are allowed)");
  struct stat st {};
  if (::stat(real.c_str(), &st) != 0)
    throw Error(ExitCode::InputNotFound, header + ": data file '" + name + "' cannot be opened (" + std::strerror(errno) + ")");
  if (!S_ISREG(st.st_mode)) invalid(header + ": data file '" + name + "' is " + file_type(st.st_mode) + ", not a regular file");
  return real.string();
}

// "slice%03d.raw 1 40 1 [dim]": the names, or empty when not a pattern.
std::vector<std::string> pattern_names(const std::string& header, const std::string& value) {
  const auto w = words(value);
  if ((w.size() != 4 && w.size() != 5) || w[0].find('%') == std::string::npos) return {};
  const std::string& f = w[0];
  const auto pc = f.find('%');
  std::size_t k = pc + 1;
  while (k < f.size() && k < pc + 3 && std::isdigit(static_cast<unsigned char>(f[k]))) ++k;
  if (k >= f.size() || f[k] != 'd' || f.find('%', k) != std::string::npos)
    invalid(header + ": data file pattern '" + f.substr(0, 40) + "' must hold one %d (or %0Nd) and no other %");
  long long lo = 0, hi = 0, step = 0;
  try {
    lo = std::stoll(w[1]), hi = std::stoll(w[2]), step = std::stoll(w[3]);
  } catch (const std::exception&) {
    invalid(header + ": data file pattern '" + value.substr(0, 60) + "' has no integer min, max and step");
  }
  if (step == 0 || (hi - lo) / step < 0 || static_cast<unsigned long long>((hi - lo) / step) >= kMaxDataFiles)
    invalid(header + ": data file pattern '" + value.substr(0, 60) + "' names more than " + std::to_string(kMaxDataFiles) +
            " files or none");
  std::vector<std::string> names;
  for (long long i = lo; step > 0 ? i <= hi : i >= hi; i += step) {
    char buf[4096];
    std::snprintf(buf, sizeof buf, f.c_str(), static_cast<int>(i));
    names.push_back(buf);
  }
  return names;
}

// Fills layout.files from a data-file field value; the lines after it are
// the names of a LIST.
void name_files(const std::string& header, const std::string& value, std::istream& rest, bool allow_external,
                DataLayout& L) {
  std::vector<std::string> names = pattern_names(header, value);
  if (names.empty() && lower(words(value).empty() ? "" : words(value)[0]) == "list") {
    std::string line;
    for (std::uint64_t n = 0; std::getline(rest, line);) {
      if (trim(line).empty()) continue;
      if (++n > kMaxDataFiles) invalid(header + ": data file LIST names more than " + std::to_string(kMaxDataFiles) + " files");
      names.push_back(trim(line));
    }
  } else if (names.empty()) {
    names.push_back(value);
  }
  for (const auto& n : names) L.files.push_back(resolve(header, n, allow_external));
}

DataLayout nrrd_layout(const std::string& header, bool allow_external) {
  DataLayout L;
  std::ifstream in(header, std::ios::binary);
  std::string line;
  if (!std::getline(in, line) || line.rfind("NRRD", 0) != 0) return L;  // the reader says why
  std::uint64_t pos = line.size() + 1;
  L.encoding = "other";
  bool skip_lines = false;
  std::string data_value;
  for (int n = 0; n < kMaxHeaderLines && std::getline(in, line); ++n) {
    pos += line.size() + 1;
    const std::string t = trim(line);
    if (t.empty()) {  // end of an attached header
      L.attached = true;
      L.offset = pos;
      break;
    }
    if (t[0] == '#' || t.find(":=") != std::string::npos) continue;
    const auto colon = t.find(':');
    if (colon == std::string::npos) continue;
    const std::string key = lower(trim(t.substr(0, colon))), value = trim(t.substr(colon + 1));
    if (key == "encoding") {
      const std::string e = lower(value);
      L.encoding = e == "raw" ? "raw" : (e == "gzip" || e == "gz") ? "gzip" : "other";
    } else if (key == "byte skip" || key == "byteskip") {
      L.skip = std::atoll(value.c_str());
    } else if (key == "line skip" || key == "lineskip") {
      skip_lines = std::atoll(value.c_str()) != 0;
    } else if (key == "data file" || key == "datafile") {
      data_value = value;
      if (lower(words(value).empty() ? "" : words(value)[0]) == "list") break;  // the names follow, to the end
    }
  }
  if (!data_value.empty()) {
    L.attached = false;
    name_files(header, data_value, in, allow_external, L);
  }
  if (!L.attached && L.files.empty()) return L;  // a header without data: the reader says why
  L.known = !skip_lines;  // line skips count lines, not bytes
  return L;
}

DataLayout meta_layout(const std::string& header, bool allow_external) {
  DataLayout L;
  std::ifstream in(header, std::ios::binary);
  std::string line;
  std::uint64_t pos = 0;
  L.encoding = "raw";
  for (int n = 0; n < kMaxHeaderLines && std::getline(in, line); ++n) {
    pos += line.size() + 1;
    const auto eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = lower(trim(line.substr(0, eq))), value = trim(line.substr(eq + 1));
    if (key == "compresseddata") L.encoding = lower(value) == "true" ? "gzip" : "raw";
    if (key == "headersize") L.skip = std::atoll(value.c_str());
    if (key != "elementdatafile") continue;
    if (lower(value) == "local") {
      L.attached = true;
      L.offset = pos;
    } else {
      name_files(header, value, in, allow_external, L);
    }
    L.known = true;
    break;
  }
  return L;
}

// Inflates the gzip or zlib stream(s) in `file` from `offset` with constant
// memory, counting at most `cap` bytes. -1: not a gzip/zlib stream.
std::int64_t inflated_bytes(const std::string& file, std::uint64_t offset, std::uint64_t cap) {
  std::ifstream in(file, std::ios::binary);
  in.seekg(static_cast<std::streamoff>(offset));
  z_stream z{};
  if (inflateInit2(&z, 15 + 32) != Z_OK) return -1;  // 15 + 32: zlib or gzip header
  std::array<unsigned char, 1 << 16> input{};
  std::array<unsigned char, 1 << 18> output{};  // discarded: only the count matters
  std::uint64_t total = 0;
  bool not_stream = false;
  while (total < cap) {
    if (z.avail_in == 0) {
      in.read(reinterpret_cast<char*>(input.data()), input.size());
      z.avail_in = static_cast<uInt>(in.gcount());
      z.next_in = input.data();
      if (z.avail_in == 0) break;  // the stream ends early: counted as short
    }
    z.next_out = output.data();
    z.avail_out = static_cast<uInt>(output.size());
    const int rc = inflate(&z, Z_NO_FLUSH);
    total += output.size() - z.avail_out;
    if (rc == Z_STREAM_END) {
      // Another gzip member may follow (concatenated .gz); anything else ends the data.
      if (z.avail_in >= 2 && z.next_in[0] == 0x1f && z.next_in[1] == 0x8b && inflateReset(&z) == Z_OK) continue;
      break;
    }
    if (rc != Z_OK && rc != Z_BUF_ERROR) {
      not_stream = true;
      break;
    }
  }
  inflateEnd(&z);
  return not_stream ? -1 : static_cast<std::int64_t>(std::min(total, cap));
}

std::uint64_t size_of(const std::string& file) {
  std::error_code ec;
  const auto s = fs::file_size(file, ec);
  return ec ? 0 : s;
}

}  // namespace

std::uint64_t effective_budget(std::uint64_t requested) {
  return requested ? requested : default_memory_budget_bytes();
}

void check_budget(const std::string& path, const std::string& what, std::uint64_t voxels, std::uint64_t budget) {
  const std::uint64_t need = pipeline_peak_bytes(voxels);
  if (budget == 0 || need <= budget) return;
  invalid(path + ": " + what + " declares " + std::to_string(voxels) + " voxels; a run needs about " + megabytes(need) +
          " (4 B x " + std::to_string(static_cast<int>(kPipelinePeakFactor)) + " per voxel), more than the memory budget of " +
          megabytes(budget) + " (raise it with --max-memory)");
}

void require_regular_file(const std::string& file, const std::string& path, const std::string& role) {
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) return;  // existence and permissions are reported by the caller
  if (!S_ISREG(st.st_mode))
    invalid(path + ": " + role + " is " + file_type(st.st_mode) + ", not a regular file (only regular files are read)");
}

DataLayout data_layout(const std::string& header, const std::string& kind, bool allow_external) {
  if (kind == "nrrd") return nrrd_layout(header, allow_external);
  if (kind == "meta") return meta_layout(header, allow_external);
  return {};
}

void check_data_holds(const std::string& header, const std::string& kind, const DataLayout& L, std::uint64_t declared) {
  if (!L.known || declared == 0) return;
  const std::string cannot = header + ": cannot read " + kind + " volume: the header declares " + std::to_string(declared);
  std::vector<std::pair<std::string, std::uint64_t>> parts;  // file, where its data starts
  if (L.attached) parts.emplace_back(header, L.offset);
  for (const auto& f : L.files) parts.emplace_back(f, 0);
  if (L.encoding == "raw") {
    if (L.skip < 0) return;  // data at the end of the file: whatever is there is read
    std::uint64_t held = 0;
    for (const auto& [f, at] : parts) {
      const std::uint64_t s = size_of(f), start = at + static_cast<std::uint64_t>(L.skip);
      held += s > start ? s - start : 0;
    }
    if (held < declared)
      invalid(cannot + " bytes of raw voxel data, the file" + (parts.size() > 1 ? "s hold " : " holds ") + std::to_string(held) +
              " (fread would get only " + std::to_string(held) + " bytes)");
    return;
  }
  if (L.encoding != "gzip") return;
  const std::uint64_t want = declared + static_cast<std::uint64_t>(std::max<std::int64_t>(L.skip, 0));
  std::uint64_t got = 0;
  for (const auto& [f, at] : parts) {
    if (got >= want) break;
    const std::int64_t n = inflated_bytes(f, at, want - got);
    if (n < 0) invalid(cannot + " bytes of compressed voxel data, but " + fs::path(f).filename().string() + " is not a gzip/zlib stream");
    got += static_cast<std::uint64_t>(n);
  }
  if (got < want)
    invalid(cannot + " bytes of voxel data, its compressed data inflates to only " + std::to_string(got));
}

namespace {

// The 348-byte NIfTI-1 header in native byte order; false when the file is
// not NIfTI-1 (NIfTI-2 and broken headers are check_nifti_payload's).
struct Nifti1 {
  unsigned char h[348];
  bool swap = false;
  std::int16_t i16(int off) const { return header_i16(h, off, swap); }
  double f32(int off) const { return header_f32(h, off, swap); }
};

bool read_nifti1(const std::string& path, Nifti1& n) {
  gzFile f = gzopen(path.c_str(), "rb");  // reads plain .nii too
  if (!f) return false;
  const int got = gzread(f, n.h, sizeof n.h);
  gzclose(f);
  if (got != static_cast<int>(sizeof n.h)) return false;
  std::int32_t size;
  std::memcpy(&size, n.h, 4);
  if (size == 348) return true;
  n.swap = true;
  return static_cast<std::int32_t>(__builtin_bswap32(static_cast<std::uint32_t>(size))) == 348;
}

const char* nifti_type_name(int datatype) {
  switch (datatype) {
    case 1: return "binary";
    case 32: return "complex64";
    case 128: return "RGB24";
    case 1536: return "float128";
    case 1792: return "complex128";
    case 2048: return "complex256";
    case 2304: return "RGBA32";
    default: return "unknown";
  }
}

using Mat3 = std::array<std::array<double, 3>, 3>;  // [row][column]

// The qform's rotation x voxel size (NIfTI-1 method 2), in RAS.
Mat3 qform_matrix(const Nifti1& n) {
  const double b = n.f32(256), c = n.f32(260), d = n.f32(264);
  const double a = std::sqrt(std::max(0.0, 1.0 - (b * b + c * c + d * d)));
  const double qfac = n.f32(76) < 0 ? -1 : 1;
  const Mat3 R = {{{a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)},
                   {2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)},
                   {2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b}}};
  const double dx[3] = {n.f32(80), n.f32(84), n.f32(88) * qfac};
  Mat3 M{};
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) M[r][k] = R[r][k] * dx[k];
  return M;
}

}  // namespace

void check_nifti_header(const std::string& path, std::uint64_t budget) {
  Nifti1 n;
  if (!read_nifti1(path, n)) return;
  const int ndim = n.i16(40);
  if (ndim < 1 || ndim > 7) return;  // check_nifti_payload refuses it
  std::uint64_t voxels = 1;
  for (int d = 1; d <= ndim; ++d) {
    const int size = n.i16(40 + 2 * d);
    if (size <= 0) return;  // check_nifti_payload refuses it
    if (d >= 4 && size > 1)
      invalid(path + ": NIfTI holds " + std::to_string(size) + " volumes along dimension " + std::to_string(d) +
              " (a 4D or higher image); MandiSym reads one 3D CT, extract the volume you mean first");
    voxels *= static_cast<std::uint64_t>(size);
  }
  static const int kScalar[] = {2, 4, 8, 16, 64, 256, 512, 768, 1024, 1280};  // (u)int8..64, float32/64
  const int datatype = n.i16(70);
  if (std::find(std::begin(kScalar), std::end(kScalar), datatype) == std::end(kScalar))
    invalid(path + ": NIfTI datatype " + std::to_string(datatype) + " (" + nifti_type_name(datatype) +
            ") is not a scalar image; a CT is one number per voxel");
  check_budget(path, "NIfTI header", voxels, budget);
}

NiftiOrientation nifti_orientation(const std::string& path, std::string* why) {
  Nifti1 n;
  if (!read_nifti1(path, n)) return NiftiOrientation::NotNifti1;
  const int qcode = n.i16(252), scode = n.i16(254);
  if (qcode <= 0 && scode <= 0) return NiftiOrientation::NotCoded;
  if (qcode <= 0 || scode <= 0) return NiftiOrientation::Consistent;
  const Mat3 Q = qform_matrix(n);
  Mat3 S{};
  double s_origin[3], q_origin[3] = {n.f32(268), n.f32(272), n.f32(276)};
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) S[r][k] = n.f32(280 + 16 * r + 4 * k);
    s_origin[r] = n.f32(280 + 16 * r + 12);
  }
  double min_voxel = 1e300;
  for (int k = 0; k < 3; ++k) {
    double qn = 0, sn = 0, dot = 0;
    for (int r = 0; r < 3; ++r) qn += Q[r][k] * Q[r][k], sn += S[r][k] * S[r][k], dot += Q[r][k] * S[r][k];
    qn = std::sqrt(qn), sn = std::sqrt(sn);
    if (!(qn > 0) || !(sn > 0)) {
      *why = "axis " + std::to_string(k + 1) + " has zero length in the " + (qn > 0 ? "sform" : "qform");
      return NiftiOrientation::Disagree;
    }
    min_voxel = std::min(min_voxel, std::min(qn, sn));
    const double deg = std::acos(std::clamp(dot / (qn * sn), -1.0, 1.0)) * 180.0 / 3.14159265358979323846;
    if (deg > kMaxAxisDisagreementDeg) {
      *why = "qform and sform disagree on axis " + std::to_string(k + 1) + " by " + std::to_string(static_cast<int>(std::lround(deg))) +
             " degrees" + (deg > 90 ? " (a flip: left/right or another axis reversed)" : "");
      return NiftiOrientation::Disagree;
    }
  }
  const double dist = std::hypot(q_origin[0] - s_origin[0], q_origin[1] - s_origin[1], q_origin[2] - s_origin[2]);
  if (dist > min_voxel) {
    std::ostringstream o;
    o.precision(3);
    o << "qform and sform origins are " << dist << " mm apart (more than one voxel, " << min_voxel << " mm)";
    *why = o.str();
    return NiftiOrientation::Disagree;
  }
  return NiftiOrientation::Consistent;
}

std::int16_t header_i16(const unsigned char* h, int off, bool swap) {
  std::uint16_t v;
  std::memcpy(&v, h + off, 2);
  return static_cast<std::int16_t>(swap ? __builtin_bswap16(v) : v);
}

std::int32_t header_i32(const unsigned char* h, int off, bool swap) {
  std::uint32_t v;
  std::memcpy(&v, h + off, 4);
  return static_cast<std::int32_t>(swap ? __builtin_bswap32(v) : v);
}

float header_f32(const unsigned char* h, int off, bool swap) {
  const std::uint32_t v = static_cast<std::uint32_t>(header_i32(h, off, swap));
  float x;
  std::memcpy(&x, &v, 4);
  return x;
}

}  // namespace ms::io::checks
