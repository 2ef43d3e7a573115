// GDCM-facing translation unit: no system Eigen here (ENGINEERING.md).
#include "io/dicom.h"

#include <gdcmAttribute.h>
#include <gdcmDataSet.h>
#include <gdcmImage.h>
#include <gdcmImageReader.h>
#include <gdcmReader.h>
#include <gdcmSequenceOfItems.h>
#include <gdcmTrace.h>

#include <algorithm>
#include <cctype>
#include <set>
#include <fstream>
#include <csignal>
#include <cmath>
#include <cstring>
#include <type_traits>
#include <filesystem>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <optional>
#include <mutex>
#include <sstream>
#include <unistd.h>
#include <fcntl.h>
#include <zlib.h>

#include "core/error.h"
#include "core/memory.h"
#include "io/volume_checks.h"

namespace fs = std::filesystem;

namespace ms::io::dicom {
namespace {

// GDCM asserts (aborts the process) on some malformed files, e.g. a file meta
// group cut in the middle of an element. Two defences: the file meta group is
// walked here first, so such a file is rejected as corrupt; and while GDCM
// reads, SIGABRT ends the process with a clear one-line error and exit code
// 4 (invalid input) instead of a core dump (docs/ingest.md, "Corrupt files").
// While GDCM reads, stderr goes to /dev/null: a failed assertion prints its
// own line before the abort (two lines instead of the one the contract
// allows); the handler writes to the saved descriptor.
char g_reading[1024] = "";
struct sigaction g_previous_abort;
int g_saved_stderr = -1;

void on_gdcm_abort(int) {
  static const char pre[] = "mandisym: error: ";
  static const char post[] = ": corrupt DICOM: the DICOM library (GDCM) gave up on it\n";
  const int fd = g_saved_stderr >= 0 ? g_saved_stderr : 2;
  (void)!::write(fd, pre, sizeof pre - 1);
  (void)!::write(fd, g_reading, ::strnlen(g_reading, sizeof g_reading));
  (void)!::write(fd, post, sizeof post - 1);
  ::_exit(4);
}

class AbortGuard {
 public:
#ifndef MANDISYM_FUZZING
  AbortGuard() {
    struct sigaction sa {};
    sa.sa_handler = on_gdcm_abort;
    ::sigaction(SIGABRT, &sa, &g_previous_abort);
    if (g_saved_stderr >= 0) return;  // nested: the outer guard has it
    std::fflush(stderr);
    const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
    if (null >= 0) {
      g_saved_stderr = ::dup(2);
      if (g_saved_stderr >= 0) ::dup2(null, 2);
      owner_ = g_saved_stderr >= 0;
      ::close(null);
    }
  }
  ~AbortGuard() {
    if (g_saved_stderr >= 0 && owner_) {
      std::fflush(stderr);
      ::dup2(g_saved_stderr, 2);
      ::close(g_saved_stderr);
      g_saved_stderr = -1;
    }
    ::sigaction(SIGABRT, &g_previous_abort, nullptr);
  }
#else
  // Fuzzing: let libFuzzer see the abort and keep the input that caused it.
  AbortGuard() { (void)on_gdcm_abort; }
  ~AbortGuard() = default;
#endif
  static void reading(const std::string& file) {
    std::strncpy(g_reading, file.c_str(), sizeof g_reading - 1);
    g_reading[sizeof g_reading - 1] = 0;
  }
  AbortGuard(const AbortGuard&) = delete;
  AbortGuard& operator=(const AbortGuard&) = delete;
#ifndef MANDISYM_FUZZING

 private:
  bool owner_ = false;  // this guard redirected stderr (the outermost one)
#endif
};

// Bounds-checked reading of the structure of a file (not of its values).
struct ByteReader {
  std::ifstream in;
  std::uintmax_t size = 0;
  bool flat_only = false;  // refuse any sequence (see structure_ok)
  std::string memory;      // when set: the bytes to walk instead of the file (an inflated data set)
  bool read(std::uintmax_t pos, unsigned char* out, std::size_t n) {
    if (pos + n > size) return false;
    if (!memory.empty()) {
      std::memcpy(out, memory.data() + pos, n);
      return true;
    }
    in.clear();
    in.seekg(static_cast<std::streamoff>(pos));
    return static_cast<bool>(in.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(n)));
  }
};

std::uint32_t le16(const unsigned char* b) { return b[0] | (b[1] << 8); }
std::uint32_t le32(const unsigned char* b) {
  return static_cast<std::uint32_t>(b[0]) | (static_cast<std::uint32_t>(b[1]) << 8) | (static_cast<std::uint32_t>(b[2]) << 16) |
         (static_cast<std::uint32_t>(b[3]) << 24);
}
bool known_vr(const char* vr) {
  static const std::set<std::string> k{"AE", "AS", "AT", "CS", "DA", "DS", "DT", "FD", "FL", "IS", "LO", "LT",
                                       "OB", "OD", "OF", "OL", "OV", "OW", "PN", "SH", "SL", "SQ", "SS", "ST",
                                       "SV", "TM", "UC", "UI", "UL", "UN", "UR", "US", "UT", "UV"};
  return k.count(std::string(vr, 2)) > 0;
}
bool long_vr(const char* vr) {
  static const std::set<std::string> k32{"OB", "OD", "OF", "OL", "OV", "OW", "SQ", "SV", "UC", "UN", "UR", "UT", "UV"};
  return k32.count(std::string(vr, 2)) > 0;
}

// Walks explicit-VR little-endian group-0002 elements from pos: true when
// they are complete and the group ends before the end of the file. end: where
// the group ends; ts: the transfer syntax UID (0002,0010).
bool walk_meta_group(ByteReader& r, std::uintmax_t pos, std::uintmax_t* end, std::string* ts) {
  for (int n = 0; n < 1000; ++n) {
    unsigned char h[12];
    if (!r.read(pos, h, 4)) return false;  // the group must end with the next group's tag
    if (le16(h) != 0x0002) {
      *end = pos;
      return true;
    }
    if (!r.read(pos + 4, h + 4, 4)) return false;
    const char vr[2] = {static_cast<char>(h[4]), static_cast<char>(h[5])};
    // GDCM's meta-group reader asserts on a VR it does not know (found by fuzzing: "UK").
    if (!known_vr(vr)) return false;
    if (vr[0] == 'S' && vr[1] == 'Q') return false;  // never in the file meta group
    std::uintmax_t len, head;
    if (long_vr(vr)) {
      if (!r.read(pos + 8, h + 8, 4)) return false;
      len = le32(h + 8), head = 12;
    } else {
      len = le16(h + 6), head = 8;
    }
    if (len == 0xFFFFFFFFu || pos + head + len > r.size) return false;
    if (le16(h + 2) == 0x0010 && len < 128) {  // transfer syntax UID
      unsigned char v[128];
      if (!r.read(pos + head, v, static_cast<std::size_t>(len))) return false;
      ts->assign(reinterpret_cast<const char*>(v), static_cast<std::size_t>(len));
      while (!ts->empty() && (ts->back() == '\0' || ts->back() == ' ')) ts->pop_back();
    }
    pos += head + len;
  }
  return false;
}

// Walks the elements of a little-endian data set from pos up to the pixel
// data (top level) or to the end of an item (nested): every declared length
// must fit in the file, so GDCM never allocates for a value the file cannot
// hold (a 1.7 kB file declared a 4 GB value). Undefined-length sequences and
// items are followed to their delimiters. Implicit VR: sequences are seen
// only when their length is undefined. Only a length past the end of the
// file counts against it (TooLong); anything else unexpected (a private
// element with an odd VR, say) stops the walk and leaves the file to GDCM.
enum class Walk { Ok, TooLong, Unsure };  // TooLong: refuse the file (a length past its end, a misplaced delimiter)

Walk walk_data_set(ByteReader& r, std::uintmax_t& pos, bool explicit_vr, int depth, bool in_item, std::uintmax_t limit,
                   bool big = false);

// Byte order of tags and lengths: little endian, or big (explicit VR big
// endian, 1.2.840.10008.1.2.2).
struct ByteOrder {
  bool big = false;
  std::uint32_t u16(const unsigned char* x) const { return big ? (x[0] << 8) | x[1] : le16(x); }
  std::uint32_t u32(const unsigned char* x) const {
    return big ? (static_cast<std::uint32_t>(x[0]) << 24) | (static_cast<std::uint32_t>(x[1]) << 16) |
                     (static_cast<std::uint32_t>(x[2]) << 8) | static_cast<std::uint32_t>(x[3])
               : le32(x);
  }
};

// The top-level pixel data element's header (h: its first 8 bytes at pos),
// walked over like any element (GDCM's full read goes on past it, so what
// follows must be sound too): TooLong for the VRs GDCM asserts on.
Walk check_pixel_data_header(ByteReader& r, std::uintmax_t pos, unsigned char* h, bool explicit_vr, const ByteOrder& o) {
  const char vr[2] = {static_cast<char>(h[4]), static_cast<char>(h[5])};
  // An unknown VR here sends GDCM into a hack for one vendor's files
  // that asserts unless the next two bytes are zero (found by fuzzing).
  if (explicit_vr && !known_vr(vr) && (h[6] != 0 || h[7] != 0)) return Walk::TooLong;
  // Encapsulated (undefined length) pixel data must be OB, OW or UN: GDCM asserts otherwise.
  if (explicit_vr && long_vr(vr) && r.read(pos + 8, h + 8, 4) && o.u32(h + 8) == 0xFFFFFFFFu &&
      !(vr[0] == 'O' && (vr[1] == 'B' || vr[1] == 'W')) && !(vr[0] == 'U' && vr[1] == 'N'))
    return Walk::TooLong;
  return Walk::Ok;
}

// An element's value length, the size of its header, and whether it is a sequence (explicit VR SQ).
struct ElementLength {
  std::uintmax_t len = 0, head = 0;
  bool sq = false;
};

// The element header at pos (h: its first 8 bytes; the next 4 are read for a
// long VR). False: refuse the file.
bool read_element_length(ByteReader& r, std::uintmax_t pos, unsigned char* h, bool explicit_vr, const ByteOrder& o,
                         ElementLength& e) {
  if (!explicit_vr) {
    e.len = o.u32(h + 4), e.head = 8;
    return true;
  }
  const char vr[2] = {static_cast<char>(h[4]), static_cast<char>(h[5])};
  if (!known_vr(vr)) {
    // Not a VR ("BS", "L\0", ...): GDCM's recovery reads the length as
    // 16 or 32 bits depending on its code path, so no walk can vouch for
    // what follows (found by fuzzing: 1.1-1.3 GB allocations). Refused.
    return false;
  } else if (long_vr(vr)) {
    if (!r.read(pos + 8, h + 8, 4)) return false;
    e.len = o.u32(h + 8), e.head = 12;
  } else {
    e.len = o.u16(h + 6), e.head = 8;
  }
  e.sq = vr[0] == 'S' && vr[1] == 'Q';
  return true;
}

// An undefined-length value from pos: a sequence of items up to (FFFE,E0DD),
// each item a data set walked at depth + 1 (inner_explicit: its VR
// encoding), or, for encapsulated pixel data (fragments), a fragment of a
// byte stream skipped over.
Walk walk_undefined_length(ByteReader& r, std::uintmax_t& pos, bool inner_explicit, bool fragments, int depth,
                           const ByteOrder& o) {
  for (int k = 0; k < 100000; ++k) {
    unsigned char it[8];
    if (!r.read(pos, it, 8)) return Walk::TooLong;
    // An item or delimiter tag in the other byte order: GDCM's workaround
    // for such files then reads a length in either order (found by
    // fuzzing: a 3.6 GB allocation from a 1 kB file). Refused.
    if (o.u16(it) == 0xFEFF && (it[2] == 0xE0 || it[3] == 0xE0)) return Walk::TooLong;
    // Anything else where an item or a delimiter belongs: the sequence is
    // broken, and GDCM's recovery asserted on it (found by fuzzing).
    if (o.u16(it) != 0xFFFE) return Walk::TooLong;
    const std::uint32_t ie = o.u16(it + 2), il = o.u32(it + 4);
    pos += 8;
    if (ie == 0xE0DD) return Walk::Ok;  // sequence delimitation
    if (ie != 0xE000) return Walk::Unsure;
    if (fragments) {
      if (il == 0xFFFFFFFFu) return Walk::Unsure;
      if (pos + il > r.size) return Walk::TooLong;
      pos += il;
      continue;
    }
    if (il == 0xFFFFFFFFu) {
      const Walk w = walk_data_set(r, pos, inner_explicit, depth + 1, true, r.size, o.big);
      if (w != Walk::Ok) return w;
    } else {
      if (pos + il > r.size) return Walk::TooLong;
      std::uintmax_t p = pos;
      const Walk w = walk_data_set(r, p, inner_explicit, depth + 1, true, pos + il, o.big);
      if (w != Walk::Ok) return w;
      pos += il;
    }
    if (k == 99999) return Walk::Unsure;
  }
  return Walk::Ok;
}

// A defined-length sequence's value, from pos to end: its items must fit in it.
Walk walk_sequence_items(ByteReader& r, std::uintmax_t& pos, std::uintmax_t end, bool explicit_vr, int depth,
                         const ByteOrder& o) {
  while (pos < end) {
    unsigned char it[8];
    if (!r.read(pos, it, 8)) return Walk::TooLong;
    if (o.u16(it) != 0xFFFE || o.u16(it + 2) != 0xE000) return Walk::TooLong;  // as in walk_undefined_length
    const std::uint32_t il = o.u32(it + 4);
    pos += 8;
    if (il == 0xFFFFFFFFu) {
      const Walk w = walk_data_set(r, pos, explicit_vr, depth + 1, true, end, o.big);
      if (w != Walk::Ok) return w;
    } else {
      if (pos + il > end) return Walk::TooLong;
      std::uintmax_t p = pos;
      const Walk w = walk_data_set(r, p, explicit_vr, depth + 1, true, pos + il, o.big);
      if (w != Walk::Ok) return w;
      pos += il;
    }
  }
  return pos > end ? Walk::TooLong : Walk::Ok;
}

Walk walk_data_set(ByteReader& r, std::uintmax_t& pos, bool explicit_vr, int depth, bool in_item, std::uintmax_t limit,
                   bool big) {
  const ByteOrder o{big};
  if (depth > 16) return Walk::Unsure;
  for (int n = 0; n < 1000000; ++n) {
    unsigned char h[12];
    // An element running past the end of its item (a nested sequence longer
    // than the item's declared length): GDCM throws, then asserts in its
    // fallback reader (found by fuzzing).
    if (pos > limit) return Walk::TooLong;
    if (pos == limit) return Walk::Ok;
    if (!r.read(pos, h, 8)) {
      // A nested item must be complete. At the top level the data set may
      // end here, but not inside an element header: with its tag readable
      // and its VR or 16-bit length cut, GDCM asserts (found by fuzzing).
      if (depth > 0) return Walk::TooLong;
      return limit - pos >= 4 ? Walk::TooLong : Walk::Ok;
    }
    const std::uint32_t group = o.u16(h), element = o.u16(h + 2);
    // Group 0000 (network command elements) never belongs in a file; an
    // empty (0000,0000) without a VR sends GDCM into a re-read that asserts
    // (found by fuzzing).
    if (group == 0x0000) return Walk::TooLong;
    if (group == 0xFFFE) {
      if (element == 0xE00D && in_item) {  // item delimitation
        pos += 8;
        return Walk::Ok;
      }
      // A delimiter or item where an element belongs: GDCM asserts on it
      // (found by fuzzing), so the file is refused here.
      return Walk::TooLong;
    }
    const bool pixel_data = group == 0x7FE0 && element == 0x0010;
    if (depth == 0 && pixel_data && check_pixel_data_header(r, pos, h, explicit_vr, o) != Walk::Ok) return Walk::TooLong;
    ElementLength e;
    if (!read_element_length(r, pos, h, explicit_vr, o, e)) return Walk::TooLong;
    pos += e.head;
    if (r.flat_only && (e.sq || e.len == 0xFFFFFFFFu)) return Walk::TooLong;
    // Explicit VR: only a sequence or UN may have an undefined length here
    // (GDCM asserts on an undefined-length OB, say; found by fuzzing).
    if (e.len == 0xFFFFFFFFu && explicit_vr && std::isupper(h[4]) && std::isupper(h[5]) && !e.sq &&
        !(h[4] == 'U' && h[5] == 'N') && !pixel_data)  // encapsulated pixel data (OB/OW, checked above)
      return Walk::TooLong;
    if (e.len == 0xFFFFFFFFu) {
      // Undefined length. (An undefined-length UN value is encoded as
      // implicit VR.) Encapsulated pixel data (e.g. a compressed icon image
      // nested in a sequence): its items are fragments of a byte stream, not data sets.
      const bool inner_explicit = explicit_vr && !(h[4] == 'U' && h[5] == 'N');
      const Walk w = walk_undefined_length(r, pos, inner_explicit, pixel_data, depth, o);
      if (w != Walk::Ok) return w;
      continue;
    }
    if (pos + e.len > r.size) return Walk::TooLong;
    if (e.sq) {  // defined-length sequence
      const Walk w = walk_sequence_items(r, pos, pos + e.len, explicit_vr, depth, o);
      if (w != Walk::Ok) return w;
      continue;
    }
    pos += e.len;
  }
  return Walk::Unsure;
}

// Inflates a raw deflate stream (no zlib header: DICOM's deflated transfer
// syntax) into out, at most cap bytes. False for a stream that is not deflate
// or inflates to nothing; a stream cut short keeps what it gave.
bool inflate_raw(const std::string& packed, std::size_t cap, std::string& out) {
  z_stream z{};
  if (inflateInit2(&z, -15) != Z_OK) return false;
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(packed.data()));
  z.avail_in = static_cast<uInt>(packed.size());
  int rc = Z_OK;
  while (rc == Z_OK && out.size() < cap) {
    const std::size_t at = out.size();
    out.resize(std::min(cap, at + (std::size_t{1} << 20)));
    z.next_out = reinterpret_cast<Bytef*>(out.data() + at);
    z.avail_out = static_cast<uInt>(out.size() - at);
    rc = inflate(&z, Z_NO_FLUSH);
    out.resize(out.size() - z.avail_out);
    if (rc == Z_BUF_ERROR && z.avail_in == 0) break;  // the stream ends without its end marker
  }
  inflateEnd(&z);
  return (rc == Z_STREAM_END || rc == Z_OK || rc == Z_BUF_ERROR) && !out.empty();
}

// False when the file cannot be handed to GDCM safely: it has the DICOM
// preamble but its file meta group (0002) is not a sequence of complete
// elements; or it has no preamble and does not start like a DICOM data set;
// or a declared length in its data set runs past the end of the file.
bool structure_ok(const std::string& file, std::uintmax_t size) {
  ByteReader r;
  r.in.open(file, std::ios::binary);
  r.size = size;
  unsigned char magic[4];
  std::uintmax_t pos = 0;
  std::string ts;
  bool big_start = false;  // no meta group and a big-endian first tag: GDCM reads it big endian
  if (r.read(128, magic, 4) && std::memcmp(magic, "DICM", 4) == 0) {
    if (!walk_meta_group(r, 132, &pos, &ts)) return false;
    // "DICM" promises a file meta group; without one GDCM guesses the byte
    // order (found by fuzzing: read big endian, a 1 GB allocation).
    if (pos == 132) return false;
  } else {
    // No preamble: only a data set that starts with a group 0008 tag (little
    // or big endian) or a little-endian file meta group goes to GDCM;
    // arbitrary bytes made its compatibility reader assert.
    unsigned char b[2];
    if (size < 8 || !r.read(0, b, 2)) return false;
    const unsigned le = le16(b), be = (b[0] << 8) | b[1];
    big_start = be == 0x0008 && le != 0x0008;
    if (le == 0x0002) {
      if (!walk_meta_group(r, 0, &pos, &ts)) return false;
    } else if (!(le == 0x0008 || be == 0x0008)) {
      return false;
    }
  }
  // The data set: little endian implicit (1.2.840.10008.1.2, also the default
  // without a meta group) or explicit (everything else but big endian and
  // deflate, which GDCM checks itself).
  if (ts == "1.2.840.10008.1.2.1.99") {
    // Deflated explicit VR little endian: the data set after the meta group is
    // a raw deflate stream. GDCM asserted on what it inflated (found by
    // fuzzing), so it is inflated here (at most 1 100 x the file, deflate's
    // limit, and 1 GB) and walked like any explicit data set.
    if (size - pos > (1u << 30)) return false;
    std::string packed(static_cast<std::size_t>(size - pos), '\0');
    if (!r.read(pos, reinterpret_cast<unsigned char*>(packed.data()), packed.size())) return false;
    std::string out;
    if (!inflate_raw(packed, std::min<std::size_t>(packed.size() * 1100 + 4096, std::size_t{1} << 30), out)) return false;
    ByteReader m;
    m.memory = std::move(out);
    m.size = m.memory.size();
    std::uintmax_t p = 0;
    return walk_data_set(m, p, true, 0, false, m.size) != Walk::TooLong;
  }
  if (ts == "1.2.840.10008.1.2.2") {
    // GDCM reads a "big endian" data set that does not start like one (group
    // 0008 in big-endian order) as little endian, guessing VRs per element,
    // so no single walk can vouch for it: refused (found by fuzzing: a 3 GB
    // allocation).
    unsigned char g[2];
    if (!r.read(pos, g, 2) || ((g[0] << 8) | g[1]) != 0x0008) return false;
    return walk_data_set(r, pos, true, 0, false, size, true) != Walk::TooLong;
  }
  if (ts.empty() && big_start) {
    // Big endian without a file meta group is the ACR-NEMA era's layout,
    // which had no sequences; GDCM re-reads nested items of such files through
    // a vendor workaround that asserts (found by fuzzing). Refused with any
    // sequence.
    r.flat_only = true;
    return walk_data_set(r, pos, true, 0, false, size, true) != Walk::TooLong;
  }
  unsigned char first[6];
  bool explicit_vr = ts.empty() ? false : ts != "1.2.840.10008.1.2";
  if (ts.empty() && r.read(pos, first, 6))  // no meta group: look at the first element
    explicit_vr = std::isupper(first[4]) && std::isupper(first[5]);
  return walk_data_set(r, pos, explicit_vr, 0, false, size) != Walk::TooLong;
}

}  // namespace

namespace {

constexpr std::size_t kMinSlices = 8;
constexpr double kAir = -1024.0;

void quiet_gdcm() {
  static std::once_flag once;
  std::call_once(once, [] {
    gdcm::Trace::SetWarning(false);
    gdcm::Trace::SetDebug(false);
    gdcm::Trace::SetError(false);
  });
}

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  std::size_t b = 0;
  while (b < s.size() && s[b] == ' ') ++b;
  return s.substr(b);
}

std::string str(const gdcm::DataSet& ds, std::uint16_t g, std::uint16_t e) {
  const gdcm::Tag t(g, e);
  if (!ds.FindDataElement(t)) return "";
  const gdcm::DataElement& de = ds.GetDataElement(t);
  const gdcm::ByteValue* bv = de.GetByteValue();
  if (!bv || de.IsEmpty()) return "";
  return trim(std::string(bv->GetPointer(), bv->GetLength()));
}

std::vector<double> numbers(const std::string& s) {
  std::vector<double> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, '\\')) {
    char* end = nullptr;
    const std::string t = trim(item);
    const double v = std::strtod(t.c_str(), &end);
    if (t.empty() || end == t.c_str() || !std::isfinite(v)) return {};
    out.push_back(v);
  }
  return out;
}

// Unsigned 16-bit value (US) in the dataset's byte order (little endian here).
bool u16(const gdcm::DataSet& ds, std::uint16_t g, std::uint16_t e, unsigned& out) {
  const gdcm::Tag t(g, e);
  if (!ds.FindDataElement(t)) return false;
  const gdcm::ByteValue* bv = ds.GetDataElement(t).GetByteValue();
  if (!bv || bv->GetLength() < 2) return false;
  std::uint16_t v;
  std::memcpy(&v, bv->GetPointer(), 2);
  out = v;
  return true;
}

const gdcm::DataSet* item(const gdcm::DataSet& ds, std::uint16_t g, std::uint16_t e, std::size_t index = 1) {
  const gdcm::Tag t(g, e);
  if (!ds.FindDataElement(t)) return nullptr;
  gdcm::SmartPointer<gdcm::SequenceOfItems> sq = ds.GetDataElement(t).GetValueAsSQ();
  if (!sq || sq->GetNumberOfItems() < index) return nullptr;
  return &sq->GetItem(index).GetNestedDataSet();
}

// |RescaleSlope| and |RescaleIntercept| above this map stored values far
// outside any CT range (-1024 to ~30 000 HU) and toward float overflow.
constexpr double kMaxRescaleMagnitude = 1e6;

// `n` finite numbers from a decimal-string tag: empty when the tag is absent;
// a present tag that does not hold them is noted in f.bad_value.
std::vector<double> field(const gdcm::DataSet& ds, std::uint16_t g, std::uint16_t e, std::size_t n, const char* name, Frame& f) {
  const std::string raw = str(ds, g, e);
  if (raw.empty()) return {};
  auto v = numbers(raw);
  if (v.size() != n) {
    if (f.bad_value.empty()) f.bad_value = std::string(name) + " '" + raw.substr(0, 64) + "' is not " + std::to_string(n) + " finite number(s)";
    return {};
  }
  return v;
}

void read_geometry(const gdcm::DataSet& ds, Frame& f) {
  const auto ipp = field(ds, 0x0020, 0x0032, 3, "ImagePositionPatient", f);
  if (ipp.size() == 3) {
    f.ipp = {ipp[0], ipp[1], ipp[2]};
    f.has_ipp = true;
  }
  const auto iop = field(ds, 0x0020, 0x0037, 6, "ImageOrientationPatient", f);
  if (iop.size() == 6) {
    f.row_dir = {iop[0], iop[1], iop[2]};
    f.col_dir = {iop[3], iop[4], iop[5]};
    f.has_iop = true;
  }
  const auto ps = field(ds, 0x0028, 0x0030, 2, "PixelSpacing", f);
  if (ps.size() == 2) {
    f.spacing_j = ps[0];  // between rows
    f.spacing_i = ps[1];  // between columns
  }
  // Rescale: a missing or unusable value is never replaced silently (one
  // slice read with intercept 0 is 1024 HU off); analyse() decides.
  f.has_intercept |= !str(ds, 0x0028, 0x1052).empty();
  f.has_slope |= !str(ds, 0x0028, 0x1053).empty();
  const auto icpt = field(ds, 0x0028, 0x1052, 1, "RescaleIntercept", f);
  const auto slope = field(ds, 0x0028, 0x1053, 1, "RescaleSlope", f);
  if (icpt.size() == 1) f.intercept = icpt[0];
  if (slope.size() == 1) f.slope = slope[0];
  if (f.bad_value.empty() && (slope.size() == 1 && (slope[0] == 0 || std::abs(slope[0]) > kMaxRescaleMagnitude)))
    f.bad_value = "RescaleSlope " + str(ds, 0x0028, 0x1053) + " is zero or beyond 1e6";
  if (f.bad_value.empty() && icpt.size() == 1 && std::abs(icpt[0]) > kMaxRescaleMagnitude)
    f.bad_value = "RescaleIntercept " + str(ds, 0x0028, 0x1052) + " is beyond 1e6";
}

// Functional group macros of an enhanced multi-frame image (shared, then per frame).
void read_functional_groups(const gdcm::DataSet& fg, Frame& f) {
  if (const auto* pos = item(fg, 0x0020, 0x9113)) read_geometry(*pos, f);
  if (const auto* ori = item(fg, 0x0020, 0x9116)) read_geometry(*ori, f);
  if (const auto* meas = item(fg, 0x0028, 0x9110)) read_geometry(*meas, f);
  if (const auto* pvt = item(fg, 0x0028, 0x9145)) read_geometry(*pvt, f);
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string fmt(double v, int prec = 2) {
  std::ostringstream o;
  o.setf(std::ios::fixed);
  o.precision(prec);
  o << v;
  return o.str();
}

std::string iop_key(const Frame& f) {
  std::ostringstream o;
  o << std::lround(f.row_dir[0] * 1000) << ',' << std::lround(f.row_dir[1] * 1000) << ',' << std::lround(f.row_dir[2] * 1000)
    << ',' << std::lround(f.col_dir[0] * 1000) << ',' << std::lround(f.col_dir[1] * 1000) << ','
    << std::lround(f.col_dir[2] * 1000) << '/' << f.rows << 'x' << f.cols;
  return f.has_iop ? o.str() : "no-iop";
}

}  // namespace

namespace {

// Discovery: the files under path, searched recursively (a file path is
// itself), sorted; entries that are neither regular files nor folders (a
// FIFO blocks forever, a device never ends, a socket) are counted, never opened.
std::vector<std::string> discover_files(const std::string& path, ScanResult& res) {
  std::vector<std::string> files;
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    for (auto it = fs::recursive_directory_iterator(path, fs::directory_options::skip_permission_denied, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
      std::error_code e2;
      if (it->is_regular_file(e2)) {
        files.push_back(it->path().string());
      } else if (!it->is_directory(e2)) {
        if (res.special_files++ == 0) res.first_special = it->path().string();
      }
    }
  } else {
    files.push_back(path);
  }
  std::sort(files.begin(), files.end());
  return files;
}

// Files are grouped by SeriesInstanceUID, then by sub-stack (orientation and matrix size, iop_key).
struct SeriesKey {
  std::string uid, stack;
  bool operator<(const SeriesKey& o) const { return std::tie(uid, stack) < std::tie(o.uid, o.stack); }
};

// The frames of one image file: itself, or an enhanced multi-frame image's
// frames placed from the shared, then the per-frame functional groups.
std::vector<Frame> frames_of(const gdcm::DataSet& ds, const Frame& base) {
  const auto nf = numbers(str(ds, 0x0028, 0x0008));
  const unsigned n_frames = nf.size() == 1 && nf[0] >= 1 ? static_cast<unsigned>(nf[0]) : 1;
  if (n_frames <= 1) return {base};
  std::vector<Frame> frames;
  Frame shared = base;
  if (const auto* sfg = item(ds, 0x5200, 0x9229)) read_functional_groups(*sfg, shared);
  for (unsigned k = 0; k < n_frames; ++k) {
    Frame f = shared;
    f.frame = k;
    if (const auto* pfg = item(ds, 0x5200, 0x9230, k + 1)) read_functional_groups(*pfg, f);
    else f.has_ipp = false;  // no per-frame position: cannot place the frame
    frames.push_back(f);
  }
  return frames;
}

// A series' attributes, from the header of its first file.
void read_series_attributes(Series& s, const gdcm::File& file, const std::string& uid, const std::string& sop_class,
                            const std::string& modality) {
  const gdcm::DataSet& ds = file.GetDataSet();
  s.uid = uid;
  s.study_uid = str(ds, 0x0020, 0x000d);
  s.frame_of_reference_uid = str(ds, 0x0020, 0x0052);
  s.modality = modality;
  s.description = str(ds, 0x0008, 0x103e);
  s.image_type = str(ds, 0x0008, 0x0008);
  s.study_date = str(ds, 0x0008, 0x0020);
  s.manufacturer = str(ds, 0x0008, 0x0070);
  s.model = str(ds, 0x0008, 0x1090);
  s.kernel = str(ds, 0x0018, 0x1210);
  s.photometric = str(ds, 0x0028, 0x0004);
  s.sop_class = sop_class;
  s.transfer_syntax = str(file.GetHeader(), 0x0002, 0x0010);
  u16(ds, 0x0028, 0x0100, s.bits_allocated);
  if (!u16(ds, 0x0028, 0x0101, s.bits_stored)) s.bits_stored = s.bits_allocated;
  u16(ds, 0x0028, 0x0103, s.pixel_representation);
  u16(ds, 0x0028, 0x0002, s.samples_per_pixel);
  unsigned pad = 0, lim = 0;
  if (u16(ds, 0x0028, 0x0120, pad)) {
    s.has_padding = true;
    s.padding = s.pixel_representation ? static_cast<double>(static_cast<std::int16_t>(pad)) : pad;
  }
  if (u16(ds, 0x0028, 0x0121, lim)) {
    s.has_padding_limit = true;
    s.padding_limit = s.pixel_representation ? static_cast<double>(static_cast<std::int16_t>(lim)) : lim;
  }
}

void note_non_dicom(ScanResult& res, const std::string& file) {
  if (res.first_non_dicom.empty()) res.first_non_dicom = file;
}

// One file's header, read with GDCM up to the pixel data (not loading it),
// and its frames added to its series. Files that cannot be read, are not
// DICOM or hold no image are counted in res.
void add_file(const std::string& file, ScanResult& res, std::map<SeriesKey, Series>& groups) {
  if (::access(file.c_str(), R_OK) != 0) {
    ++res.unreadable_files;
    if (res.first_unreadable.empty()) res.first_unreadable = file;
    return;
  }
  std::error_code ec;
  const auto size = fs::file_size(file, ec);
  if (!ec && !structure_ok(file, size)) return note_non_dicom(res, file);
  AbortGuard::reading(file);
  gdcm::Reader r;
  r.SetFileName(file.c_str());
  // Headers only: stop in front of the pixel data (the skip set keeps GDCM
  // from loading it); the bytes left tell whether there is any.
  static const std::set<gdcm::Tag> kSkipPixels{gdcm::Tag(0x7fe0, 0x0010)};
  if (ec || size < 16 || !r.ReadUpToTag(gdcm::Tag(0x7fe0, 0x0010), kSkipPixels)) return note_non_dicom(res, file);
  const gdcm::DataSet& ds = r.GetFile().GetDataSet();
  const std::string sop_class = str(ds, 0x0008, 0x0016);
  const std::string modality = str(ds, 0x0008, 0x0060);
  if (ds.IsEmpty() || (sop_class.empty() && modality.empty() && !ds.FindDataElement(gdcm::Tag(0x0028, 0x0010))))
    return note_non_dicom(res, file);
  ++res.dicom_files;
  unsigned rows = 0, cols = 0;
  if (!u16(ds, 0x0028, 0x0010, rows) || !u16(ds, 0x0028, 0x0011, cols) || rows == 0 || cols == 0) {
    ++res.non_image_files;
    return;
  }
  const std::size_t pos = r.GetStreamCurrentPosition();  // (size_t)-1 at end of file
  const bool has_pixels = pos != static_cast<std::size_t>(-1) && pos + 8 <= size;
  Frame base;
  base.file = file;
  base.rows = rows;
  base.cols = cols;
  base.instance = static_cast<int>(std::lround(numbers(str(ds, 0x0020, 0x0013)).empty() ? 0 : numbers(str(ds, 0x0020, 0x0013))[0]));
  base.sop_instance_uid = str(ds, 0x0008, 0x0018);
  read_geometry(ds, base);
  std::vector<Frame> frames = frames_of(ds, base);
  const std::string uid = str(ds, 0x0020, 0x000e);
  Series& s = groups[SeriesKey{uid.empty() ? "(no SeriesInstanceUID)" : uid, iop_key(frames.front())}];
  if (s.frames.empty()) read_series_attributes(s, r.GetFile(), uid, sop_class, modality);
  if (!has_pixels && !s.missing_pixel_data) {
    s.missing_pixel_data = true;
    s.missing_pixel_data_file = file;
  }
  s.files.insert(file);
  for (auto& f : frames) s.frames.push_back(std::move(f));
}

}  // namespace

ScanResult scan(const std::string& path) {
  quiet_gdcm();
  const AbortGuard guard;
  ScanResult res;
  res.path = path;
  const std::vector<std::string> files = discover_files(path, res);
  res.files_seen = files.size();
  std::map<SeriesKey, Series> groups;
  for (const auto& file : files) add_file(file, res, groups);
  // Label sub-stacks of one UID as uid#1, uid#2, ...
  std::map<std::string, int> per_uid;
  for (const auto& [k, s] : groups) ++per_uid[k.uid];
  std::map<std::string, int> seen;
  for (auto& [k, s] : groups) {
    s.label = per_uid[k.uid] > 1 ? k.uid + "#" + std::to_string(++seen[k.uid]) : k.uid;
    res.series.push_back(std::move(s));
  }
  return res;
}

namespace {

// Geometry no scan has (docs/ingest.md, "Geometry"): a position beyond 10 m
// (an x of 1e300 mm ended in SIGFPE in the mesh stage), a pixel size outside
// 1 micrometre to 10 cm, orientation vectors that are not unit and orthogonal.
std::string gfmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

std::string absurd_geometry(const Frame& f) {
  for (int a = 0; a < 3; ++a)
    if (!(std::abs(f.ipp[a]) <= checks::kMaxPositionMm))
      return "ImagePositionPatient " + gfmt(f.ipp[a]) + " mm is beyond 10 m";
  for (double sp : {f.spacing_i, f.spacing_j})
    if (!(sp >= checks::kMinSpacingMm && sp <= checks::kMaxSpacingMm))
      return "PixelSpacing " + gfmt(sp) + " mm is outside 0.001 to 100 mm";
  if (std::abs(dot(f.row_dir, f.col_dir)) > 1e-3 || std::abs(norm(f.row_dir) - 1) > 1e-3 || std::abs(norm(f.col_dir) - 1) > 1e-3)
    return "ImageOrientationPatient is not orthonormal";
  return "";
}

// RescaleSlope and RescaleIntercept are Type 1 in the CT Image module
// (PS3.3 C.8.2.1): present on some slices of a series but not on others is an
// error naming the first slice without; absent from every slice, the stored
// values are taken as HU (slope 1, intercept 0) with a warning.
std::string rescale_presence(const Series& s, std::vector<std::string>& warnings) {
  for (const char* tag : {"RescaleIntercept", "RescaleSlope"}) {
    const bool intercept = tag[7] == 'I';
    std::size_t with = 0;
    const Frame* without = nullptr;
    for (const auto& f : s.frames) {
      const bool has = intercept ? f.has_intercept : f.has_slope;
      with += has;
      if (!has && !without) without = &f;
    }
    if (with == 0)
      warnings.push_back(std::string(tag) + " missing from every slice (Type 1 in CT): stored values taken as HU with " +
                         (intercept ? "intercept 0" : "slope 1") + "; check --hu-offset");
    else if (without)
      return without->file + ": " + tag + " missing while other slices of the series have it";
  }
  return "";
}

}  // namespace

Layout analyse(const Series& s) {
  Layout L;
  auto refuse = [&](const std::string& why) {
    L.usable = false;
    L.problem = why;
    return L;
  };
  if (s.missing_pixel_data) return refuse(s.missing_pixel_data_file + ": DICOM image without pixel data");
  if (s.samples_per_pixel != 1) return refuse("colour images (" + std::to_string(s.samples_per_pixel) + " samples per pixel) are not CT");
  for (const auto& f : s.frames) {
    if (!f.bad_value.empty()) return refuse(f.file + ": " + f.bad_value);
    if (!f.has_ipp || !f.has_iop)
      return refuse(f.file + ": ImagePositionPatient or ImageOrientationPatient missing; the slice cannot be placed");
    if (!(f.spacing_i > 0) || !(f.spacing_j > 0)) return refuse(f.file + ": PixelSpacing missing or not positive");
    if (const std::string bad = absurd_geometry(f); !bad.empty()) return refuse(f.file + ": " + bad);
  }
  if (const std::string bad = rescale_presence(s, L.warnings); !bad.empty()) return refuse(bad);
  if (s.frames.size() < kMinSlices)
    return refuse(s.frames.size() == 1 ? "a single slice, not a volume"
                                       : std::to_string(s.frames.size()) + " slices, too few for a head CT volume");
  const Frame& f0 = s.frames.front();
  for (const auto& f : s.frames)
    if (std::abs(f.spacing_i - f0.spacing_i) > 1e-3 * f0.spacing_i || std::abs(f.spacing_j - f0.spacing_j) > 1e-3 * f0.spacing_j)
      return refuse("pixel spacing differs between slices (" + f0.file + ": " + fmt(f0.spacing_j, 4) + "\\" +
                    fmt(f0.spacing_i, 4) + ", " + f.file + ": " + fmt(f.spacing_j, 4) + "\\" + fmt(f.spacing_i, 4) + ")");
  if (std::abs(dot(f0.row_dir, f0.col_dir)) > 1e-3 || std::abs(norm(f0.row_dir) - 1) > 1e-3 || std::abs(norm(f0.col_dir) - 1) > 1e-3)
    return refuse(f0.file + ": ImageOrientationPatient is not orthonormal");
  L.normal = normalized(cross(f0.row_dir, f0.col_dir));
  // Sort along the normal.
  std::vector<std::size_t> idx(s.frames.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  std::stable_sort(idx.begin(), idx.end(), [&](std::size_t a, std::size_t b) {
    return dot(L.normal, s.frames[a].ipp) < dot(L.normal, s.frames[b].ipp);
  });
  // Duplicates: same position (3D) as the previous kept frame.
  for (std::size_t k = 0; k < idx.size(); ++k) {
    if (!L.order.empty()) {
      const Frame& prev = s.frames[L.order.back()];
      const Frame& cur = s.frames[idx[k]];
      if (distance(prev.ipp, cur.ipp) < 0.01) {
        L.duplicates.back().push_back(idx[k]);
        continue;
      }
      if (std::abs(dot(L.normal, cur.ipp - prev.ipp)) < 0.01)
        return refuse("two slices at the same level with different in-plane positions (" + prev.file + ", " + cur.file + ")");
    }
    L.order.push_back(idx[k]);
    L.duplicates.emplace_back();
  }
  if (L.order.size() < kMinSlices)
    return refuse(std::to_string(L.order.size()) + " distinct slice positions, too few for a head CT volume");
  std::vector<double> t;
  for (auto i : L.order) t.push_back(dot(L.normal, s.frames[i].ipp));
  std::vector<double> d;
  for (std::size_t k = 1; k < t.size(); ++k) d.push_back(t[k] - t[k - 1]);
  std::vector<double> sorted = d;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  L.nominal_spacing = sorted[sorted.size() / 2];
  L.extent_mm = t.back() - t.front();
  L.max_gap = *std::max_element(d.begin(), d.end());
  const double min_gap = *std::min_element(d.begin(), d.end());
  // Gantry tilt: the stack direction is not the slice normal.
  const Vec3 stack = s.frames[L.order.back()].ipp - s.frames[L.order.front()].ipp;
  L.tilt_deg = std::acos(std::min(1.0, std::abs(dot(normalized(stack), L.normal)))) * 180.0 / 3.14159265358979323846;
  if (L.tilt_deg > 0.1) {
    if (L.tilt_deg > 45) return refuse("slice positions do not advance along the slice normal (tilt " + fmt(L.tilt_deg, 1) + "°)");
    L.resample = true;
    L.warnings.push_back("gantry tilt of " + fmt(L.tilt_deg, 1) + "° corrected by resampling onto an orthogonal grid");
  }
  const double tol = std::max(0.02, 0.05 * L.nominal_spacing);
  if (L.max_gap > L.nominal_spacing + tol || min_gap < L.nominal_spacing - tol) {
    if (L.max_gap > 3.0 * L.nominal_spacing + tol) {
      std::size_t k = 0;
      while (d[k] != L.max_gap) ++k;
      return refuse("slices missing: a gap of " + fmt(L.max_gap) + " mm (nominal spacing " + fmt(L.nominal_spacing) +
                    " mm) between " + s.frames[L.order[k]].file + " and " + s.frames[L.order[k + 1]].file);
    }
    L.resample = true;
    const long missing = std::lround(L.extent_mm / L.nominal_spacing) + 1 - static_cast<long>(L.order.size());
    L.warnings.push_back("non-uniform slice spacing (" + fmt(min_gap) + " to " + fmt(L.max_gap) + " mm, nominal " +
                         fmt(L.nominal_spacing) + " mm" + (missing > 0 ? ", about " + std::to_string(missing) + " missing slice(s)" : "") +
                         "): resampled by linear interpolation");
  }
  std::size_t dups = 0;
  for (const auto& g : L.duplicates) dups += g.size();
  if (dups) L.warnings.push_back(std::to_string(dups) + " slice(s) at an already used position (checked for identical content when read)");
  const Vec3& n = L.normal;
  L.orientation = std::abs(n[2]) > 0.9 ? "axial" : std::abs(n[1]) > 0.9 ? "coronal" : std::abs(n[0]) > 0.9 ? "sagittal" : "oblique";
  L.usable = true;
  return L;
}

int choose(const ScanResult& scan, const std::vector<Layout>& layouts, std::string* why) {
  int best = -1;
  double best_extent = 0;
  for (std::size_t i = 0; i < scan.series.size(); ++i) {
    const auto& s = scan.series[i];
    if (lower(s.modality) != "ct" || !layouts[i].usable || lower(s.image_type).find("localizer") != std::string::npos) continue;
    best_extent = std::max(best_extent, layouts[i].extent_mm);
  }
  for (std::size_t i = 0; i < scan.series.size(); ++i) {
    const auto& s = scan.series[i];
    const Layout& L = layouts[i];
    if (lower(s.modality) != "ct" || !L.usable || lower(s.image_type).find("localizer") != std::string::npos) continue;
    if (L.extent_mm < 0.8 * best_extent) continue;  // must cover (nearly) as much as the best
    if (best < 0) {
      best = static_cast<int>(i);
      continue;
    }
    const auto& b = scan.series[best];
    const double vox = s.frames[0].spacing_i * s.frames[0].spacing_j * L.nominal_spacing;
    const double bvox = b.frames[0].spacing_i * b.frames[0].spacing_j * layouts[best].nominal_spacing;
    if (vox < bvox * 0.999 || (std::abs(vox - bvox) <= bvox * 0.001 && L.order.size() > layouts[best].order.size()))
      best = static_cast<int>(i);
  }
  if (!why) return best;
  if (best >= 0) {
    *why = "CT series " + scan.series[best].label + " (" + std::to_string(layouts[best].order.size()) +
           " slices): the finest series covering at least 80 % of the largest extent";
    return best;
  }
  // Explain the refusal.
  std::map<std::string, std::size_t> modalities;
  int largest_ct = -1;
  for (std::size_t i = 0; i < scan.series.size(); ++i) {
    const auto& s = scan.series[i];
    modalities[s.modality.empty() ? "unknown modality" : s.modality] += s.frames.size();
    if (lower(s.modality) == "ct" && (largest_ct < 0 || s.frames.size() > scan.series[largest_ct].frames.size()))
      largest_ct = static_cast<int>(i);
  }
  if (largest_ct >= 0) {
    const auto& L = layouts[largest_ct];
    *why = L.usable ? "the only CT series is a localizer" : L.problem;
  } else {
    std::string found;
    for (const auto& [m, n] : modalities) found += (found.empty() ? "" : ", ") + m + " (" + std::to_string(n) + " images)";
    *why = "no CT series; found " + found;
  }
  return -1;
}

namespace {

// Takes n stored values of B bytes each (little endian, as GDCM returns
// them) and the bits actually stored; writes their integer values to out:
// bits above BitsStored (overlays) dropped, two's complement sign-extended
// from the top stored bit when is_signed. One loop per width so that the
// compiler sees fixed-size loads (this loop is most of the DICOM decode time).
template <unsigned B>
void unpack_stored(const char* buf, std::size_t n, unsigned stored, bool is_signed, double* out) {
  const std::uint32_t mask = stored >= 32 ? ~0u : (1u << stored) - 1u;
  const std::uint32_t sign = stored >= 32 ? 0x80000000u : 1u << (stored - 1);
  const std::int64_t wrap = static_cast<std::int64_t>(1) << std::min(stored, 32u);
  for (std::size_t i = 0; i < n; ++i) {
    std::conditional_t<B == 1, std::uint8_t, std::conditional_t<B == 2, std::uint16_t, std::uint32_t>> word;
    std::memcpy(&word, buf + i * B, B);
    const std::uint32_t raw = static_cast<std::uint32_t>(word) & mask;
    out[i] = is_signed && (raw & sign) ? static_cast<double>(static_cast<std::int64_t>(raw) - wrap) : static_cast<double>(raw);
  }
}

// The frame size a compressed stream declares in its own header (JPEG and
// JPEG-LS: the SOF segment; JPEG 2000: the SIZ segment): the codec allocates
// by it. False when the fragment does not start a stream or none is found.
bool declared_frame_size(const unsigned char* b, std::size_t n, unsigned& rows, unsigned& cols) {
  if (n >= 4 && b[0] == 0xFF && b[1] == 0xD8) {  // JPEG / JPEG-LS: walk the marker segments to the SOF
    for (std::size_t p = 2; p + 4 <= n;) {
      if (b[p] != 0xFF) return false;
      const unsigned m = b[p + 1];
      if (m == 0xFF) { ++p; continue; }  // fill byte
      if (m == 0x01 || (m >= 0xD0 && m <= 0xD8)) { p += 2; continue; }  // no length
      const bool sof = (m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC) || m == 0xF7;  // F7: JPEG-LS
      if (sof) {
        if (p + 9 > n) return false;
        rows = (b[p + 5] << 8) | b[p + 6];
        cols = (b[p + 7] << 8) | b[p + 8];
        return true;
      }
      if (m == 0xDA) return false;  // scan data before any frame header
      p += 2 + ((b[p + 2] << 8) | b[p + 3]);
    }
    return false;
  }
  auto be32 = [&](std::size_t p) { return (std::uint32_t{b[p]} << 24) | (b[p + 1] << 16) | (b[p + 2] << 8) | b[p + 3]; };
  for (std::size_t p = 0; p + 24 <= n && p < 4096; ++p)  // JPEG 2000 codestream, bare or in a JP2 box: SOC + SIZ
    if (b[p] == 0xFF && b[p + 1] == 0x4F && b[p + 2] == 0xFF && b[p + 3] == 0x51) {
      const std::uint32_t x = be32(p + 8), y = be32(p + 12), x0 = be32(p + 16), y0 = be32(p + 20);
      cols = x >= x0 ? x - x0 : 0;
      rows = y >= y0 ? y - y0 : 0;
      return true;
    }
  return false;
}

// Every compressed frame's own header must declare the Rows x Columns of the
// DICOM header (found by an attacker: a 17 kB slice whose JPEG claimed 60000 x
// 60000 made the codec allocate 18 GB before failing).
void check_compressed_frames(const gdcm::SequenceOfFragments& sf, const std::string& file, unsigned rows, unsigned cols) {
  for (unsigned i = 0; i < sf.GetNumberOfFragments(); ++i) {
    const gdcm::ByteValue* bv = sf.GetFragment(i).GetByteValue();
    if (!bv || !bv->GetPointer()) continue;
    unsigned r = 0, c = 0;
    const auto* b = reinterpret_cast<const unsigned char*>(bv->GetPointer());
    if (!declared_frame_size(b, std::min<std::size_t>(bv->GetLength(), 1 << 16), r, c)) continue;
    if (r != rows || c != cols)
      throw Error(ExitCode::InputInvalid, file + ": compressed pixel data declares a " + std::to_string(r) + " x " +
                                              std::to_string(c) + " frame, the DICOM header " + std::to_string(rows) + " x " +
                                              std::to_string(cols) + " (Rows x Columns)");
  }
}

// BitsAllocated, BitsStored and PixelRepresentation are read from the first
// file of a series; every file must agree (its pixel data is unpacked by them).
void check_pixel_format(const gdcm::DataSet& ds, const Series& s, const std::string& file) {
  unsigned v = 0;
  if (u16(ds, 0x0028, 0x0100, v) && v != s.bits_allocated)
    throw Error(ExitCode::InputInvalid, file + ": BitsAllocated " + std::to_string(v) + " differs from the series' " +
                                            std::to_string(s.bits_allocated));
  if (u16(ds, 0x0028, 0x0103, v) && v != s.pixel_representation)
    throw Error(ExitCode::InputInvalid, file + ": PixelRepresentation " + std::to_string(v) + " differs from the series' " +
                                            std::to_string(s.pixel_representation));
}

// Stored values of every frame of a file, as doubles, frame-major.
std::vector<double> decode_file(const Series& s, const std::string& file, unsigned rows, unsigned cols, unsigned n_frames) {
  gdcm::ImageReader ir;
  ir.SetFileName(file.c_str());
  if (!ir.Read()) {
    gdcm::Reader plain;  // tell "no pixel data" apart from corruption
    plain.SetFileName(file.c_str());
    if (plain.Read() && !plain.GetFile().GetDataSet().FindDataElement(gdcm::Tag(0x7fe0, 0x0010)))
      throw Error(ExitCode::InputInvalid, file + ": DICOM image without pixel data");
    throw Error(ExitCode::InputInvalid, file + ": cannot read the image (truncated or corrupt DICOM)");
  }
  const gdcm::Image& img = ir.GetImage();
  const std::size_t n = static_cast<std::size_t>(rows) * cols * n_frames;
  const unsigned bytes = s.bits_allocated / 8;
  if (bytes != 1 && bytes != 2 && bytes != 4)
    throw Error(ExitCode::InputInvalid, file + ": unsupported BitsAllocated " + std::to_string(s.bits_allocated));
  // GDCM sizes its buffer from Rows x Columns and zero-fills what the file
  // lacks: check the bytes actually present for native pixel data.
  const gdcm::DataSet& ds = ir.GetFile().GetDataSet();
  if (!ds.FindDataElement(gdcm::Tag(0x7fe0, 0x0010)))
    throw Error(ExitCode::InputInvalid, file + ": DICOM image without pixel data");
  const gdcm::DataElement& pd = ds.GetDataElement(gdcm::Tag(0x7fe0, 0x0010));
  check_pixel_format(ds, s, file);
  if (const gdcm::ByteValue* bv = pd.GetByteValue()) {
    if (bv->GetLength() < n * bytes)
      throw Error(ExitCode::InputInvalid, file + ": pixel data holds " + std::to_string(bv->GetLength()) +
                                              " bytes, Rows x Columns x frames needs " + std::to_string(n * bytes) +
                                              " (truncated file or wrong Rows/Columns)");
    // Longer than Rows x Columns x frames x BitsAllocated/8 (one pad byte
    // for an odd length aside): the header does not describe these pixels
    // (BitsAllocated 8 over 16-bit data read as noise, "no bone").
    if (bv->GetLength() > n * bytes + 1)
      throw Error(ExitCode::InputInvalid, file + ": pixel data holds " + std::to_string(bv->GetLength()) +
                                              " bytes, Rows x Columns x frames x BitsAllocated/8 is " + std::to_string(n * bytes) +
                                              " (wrong BitsAllocated, Rows, Columns or NumberOfFrames)");
  } else if (const gdcm::SequenceOfFragments* sf = pd.GetSequenceOfFragments()) {
    check_compressed_frames(*sf, file, rows, cols);
  } else {
    throw Error(ExitCode::InputInvalid, file + ": DICOM image without pixel data");
  }
  const unsigned long len = img.GetBufferLength();
  if (len < n * bytes)
    throw Error(ExitCode::InputInvalid, file + ": pixel data holds " + std::to_string(len) + " bytes, Rows x Columns x frames needs " +
                                            std::to_string(n * bytes));
  std::vector<char> buf(len);
  if (!img.GetBuffer(buf.data()))
    throw Error(ExitCode::InputInvalid, file + ": cannot decode the pixel data (" +
                                            std::string(img.GetTransferSyntax().GetString() ? img.GetTransferSyntax().GetString() : "?") + ")");
  std::vector<double> out(n);
  const bool is_signed = s.pixel_representation == 1;
  const unsigned stored = s.bits_stored == 0 ? s.bits_allocated : std::min(s.bits_stored, s.bits_allocated);
  if (bytes == 1)
    unpack_stored<1>(buf.data(), n, stored, is_signed, out.data());
  else if (bytes == 2)
    unpack_stored<2>(buf.data(), n, stored, is_signed, out.data());
  else
    unpack_stored<4>(buf.data(), n, stored, is_signed, out.data());
  return out;
}

// Codec libraries (libjpeg, OpenJPEG) print to stderr on corrupt streams; our
// own one-line error says what happened. Redirects fd 2 to /dev/null for the
// lifetime of the object (decoding only; nothing else prints meanwhile).
class SilenceStderr {
 public:
  SilenceStderr() {
    std::fflush(stderr);
    saved_ = ::dup(2);
    const int devnull = ::open("/dev/null", O_WRONLY);
    if (saved_ >= 0 && devnull >= 0) ::dup2(devnull, 2);
    if (devnull >= 0) ::close(devnull);
  }
  ~SilenceStderr() {
    std::fflush(stderr);
    if (saved_ >= 0) {
      ::dup2(saved_, 2);
      ::close(saved_);
    }
  }
  SilenceStderr(const SilenceStderr&) = delete;
  SilenceStderr& operator=(const SilenceStderr&) = delete;

 private:
  int saved_ = -1;
};

}  // namespace

bool safe_to_parse(const std::string& file) {
  std::error_code ec;
  const auto size = fs::file_size(file, ec);
  return !ec && structure_ok(file, size);
}

namespace {

// Values: a stored value equal to PixelPaddingValue (or within the range it
// spans with Pixel Padding Range Limit) is padding.
bool is_padding(const Series& s, double v) {
  if (!s.has_padding) return false;
  if (s.has_padding_limit) return v >= std::min(s.padding, s.padding_limit) && v <= std::max(s.padding, s.padding_limit);
  return v == s.padding;
}

// Values of one frame (src: its stored values): HU = stored x RescaleSlope +
// RescaleIntercept, per slice; padding becomes air, values below air are set
// to air. Counts both.
void frame_hu(const Series& s, const Frame& fr, const double* src, std::size_t plane, float* out, std::size_t& padded,
              std::size_t& clamped) {
  for (std::size_t p = 0; p < plane; ++p) {
    const double v = src[p];
    const bool pad = is_padding(s, v);
    double h = pad ? kAir : v * fr.slope + fr.intercept;
    if (pad) ++padded;
    if (h < kAir) {
      h = kAir;
      ++clamped;
    }
    out[p] = static_cast<float>(h);
  }
}

// The frames the layout uses (its order and its duplicates) in HU, decoded
// file by file in parallel; the padding voxels counted. A frame of the
// layout's order goes straight into slice k of `slices` when given (no
// resampling: the volume is written once, not copied from per-frame
// buffers); the others (duplicates, or every frame without `slices`) into
// their own buffers. Throws the first decoding error, naming its file.
struct DecodedFrames {
  std::vector<std::vector<float>> hu;  // by frame index; empty for frames in `slices` or unused
  std::vector<const float*> at;        // by frame index: its pixels, wherever they are
  std::size_t padded = 0;
};

DecodedFrames decode_frames(const Series& s, const Layout& L, unsigned rows, unsigned cols, float* slices) {
  const std::size_t plane = static_cast<std::size_t>(rows) * cols;
  std::vector<long> slice_of(s.frames.size(), -1);
  if (slices)
    for (std::size_t k = 0; k < L.order.size(); ++k) slice_of[L.order[k]] = static_cast<long>(k);
  std::map<std::string, std::vector<std::size_t>> by_file;  // the frames needed, grouped by file
  std::vector<std::size_t> needed = L.order;
  for (const auto& g : L.duplicates) needed.insert(needed.end(), g.begin(), g.end());
  for (auto i : needed) by_file[s.frames[i].file].push_back(i);
  std::vector<std::string> file_list;
  for (const auto& [f, v] : by_file) file_list.push_back(f);
  DecodedFrames out;
  out.hu.resize(s.frames.size());
  std::size_t padded = 0, clamped = 0;
  std::string error;
  std::mutex mu;
  std::optional<SilenceStderr> silence;
  if (!std::getenv("MANDISYM_DEBUG_CODECS")) silence.emplace();
#pragma omp parallel for schedule(dynamic, 4) reduction(+ : padded, clamped)
  for (long fi = 0; fi < static_cast<long>(file_list.size()); ++fi) {
    const std::string& file = file_list[static_cast<std::size_t>(fi)];
    std::vector<double> stored;
    try {
      unsigned in_file = 0;  // frames of this file (multi-frame files decode as one buffer)
      for (const auto& fr : s.frames)
        if (fr.file == file) ++in_file;
      stored = decode_file(s, file, rows, cols, in_file);
    } catch (const std::exception& e) {  // nothing may escape the parallel region
      std::lock_guard<std::mutex> lock(mu);
      if (error.empty()) error = e.what();
      continue;
    }
    for (auto i : by_file.at(file)) {
      const Frame& fr = s.frames[i];
      float* dst = nullptr;
      if (slice_of[i] >= 0) {
        dst = slices + static_cast<std::size_t>(slice_of[i]) * plane;
      } else {
        out.hu[i].resize(plane);
        dst = out.hu[i].data();
      }
      frame_hu(s, fr, stored.data() + static_cast<std::size_t>(fr.frame) * plane, plane, dst, padded, clamped);
    }
  }
  silence.reset();
  if (!error.empty()) throw Error(ExitCode::InputInvalid, error);
  (void)clamped;  // values below -1024 HU outside the reconstruction circle are routine
  out.padded = padded;
  out.at.resize(s.frames.size(), nullptr);
  for (std::size_t i = 0; i < s.frames.size(); ++i)
    out.at[i] = slice_of[i] >= 0 ? slices + static_cast<std::size_t>(slice_of[i]) * plane : out.hu[i].empty() ? nullptr : out.hu[i].data();
  return out;
}

// Duplicates: slices at a position already used must be identical to the
// slice kept there (dropped); different images there are refused, naming both.
// Returns the number dropped.
std::size_t exact_duplicates(const Series& s, const Layout& L, const DecodedFrames& d, std::size_t plane) {
  std::size_t dropped = 0;
  for (std::size_t k = 0; k < L.order.size(); ++k)
    for (auto dup : L.duplicates[k]) {
      if (!std::equal(d.at[dup], d.at[dup] + plane, d.at[L.order[k]]))
        throw Error(ExitCode::InputInvalid, "two different images at the same position: " + s.frames[L.order[k]].file + " and " +
                                                s.frames[dup].file + " (interleaved acquisitions?)");
      ++dropped;
    }
  return dropped;
}

// Bilinear sample of one frame's HU (img) at LPS point p; air outside it.
double sample_frame(const Frame& fr, const float* img, const Vec3& r, const Vec3& c, unsigned rows, unsigned cols,
                    const Vec3& p) {
  const Vec3 q = p - fr.ipp;
  const double x = dot(q, r) / fr.spacing_i, y = dot(q, c) / fr.spacing_j;
  if (x < 0 || y < 0 || x > cols - 1 || y > rows - 1) return kAir;
  const std::size_t x0 = std::min<std::size_t>(static_cast<std::size_t>(x), cols - 2), y0 = std::min<std::size_t>(static_cast<std::size_t>(y), rows - 2);
  const double ax = x - x0, ay = y - y0;
  const double a = img[y0 * cols + x0], b = img[y0 * cols + x0 + 1], cc = img[(y0 + 1) * cols + x0], d = img[(y0 + 1) * cols + x0 + 1];
  return (1 - ay) * ((1 - ax) * a + ax * b) + ay * ((1 - ax) * cc + ax * d);
}

// Tilt and gaps: the slices resampled onto the orthogonal grid (row, column,
// normal) of v's spacing and direction that covers every frame's in-plane
// footprint; linear between the bracketing frames, bilinear within each.
// The grid is refused when a run on it would exceed the memory budget.
void resample_frames(Volume& v, const Series& s, const Layout& L, const std::vector<const float*>& hu,
                     std::uint64_t memory_budget) {
  Geometry& g = v.geom;
  const Frame& f0 = s.frames[L.order.front()];
  const unsigned rows = f0.rows, cols = f0.cols;
  const Vec3 r = f0.row_dir, c = f0.col_dir, n = L.normal;
  double lo_r = 1e30, hi_r = -1e30, lo_c = 1e30, hi_c = -1e30;
  std::vector<double> t;
  for (auto i : L.order) {
    const Frame& fr = s.frames[i];
    lo_r = std::min(lo_r, dot(fr.ipp, r));
    hi_r = std::max(hi_r, dot(fr.ipp, r) + (cols - 1) * fr.spacing_i);
    lo_c = std::min(lo_c, dot(fr.ipp, c));
    hi_c = std::max(hi_c, dot(fr.ipp, c) + (rows - 1) * fr.spacing_j);
    t.push_back(dot(fr.ipp, n));
  }
  g.size = {static_cast<std::size_t>(std::floor((hi_r - lo_r) / g.spacing[0] + 1e-6)) + 1,
            static_cast<std::size_t>(std::floor((hi_c - lo_c) / g.spacing[1] + 1e-6)) + 1,
            static_cast<std::size_t>(std::floor((t.back() - t.front()) / g.spacing[2] + 1e-6)) + 1};
  g.origin = lo_r * r + lo_c * c + t.front() * n;
  checks::check_budget(f0.file, "the resampled grid of its series (" + std::to_string(g.size[0]) + " x " +
                                    std::to_string(g.size[1]) + " x " + std::to_string(g.size[2]) + ")",
                       static_cast<std::uint64_t>(std::min(1e19L, static_cast<long double>(g.size[0]) * g.size[1] * g.size[2])),
                       memory_budget);
  v.hu.assign(g.voxel_count(), static_cast<float>(kAir));
  const long nz = static_cast<long>(g.size[2]);
#pragma omp parallel for schedule(static)
  for (long k = 0; k < nz; ++k) {
    const double tk = t.front() + k * g.spacing[2];
    std::size_t hi = static_cast<std::size_t>(std::upper_bound(t.begin(), t.end(), tk + 1e-6) - t.begin());
    hi = std::min(std::max<std::size_t>(hi, 1), t.size() - 1);
    const std::size_t lo = hi - 1;
    const double w = std::clamp((tk - t[lo]) / (t[hi] - t[lo]), 0.0, 1.0);
    const std::size_t flo = L.order[lo], fhi = L.order[hi];
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        const Vec3 p = g.index_to_lps(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
        const double a = sample_frame(s.frames[flo], hu[flo], r, c, rows, cols, p);
        const double b = sample_frame(s.frames[fhi], hu[fhi], r, c, rows, cols, p);
        v.hu[g.linear(i, j, static_cast<std::size_t>(k))] = static_cast<float>((1 - w) * a + w * b);
      }
  }
}

}  // namespace

Volume assemble(const Series& s, const Layout& L, std::vector<std::string>& warnings, std::uint64_t memory_budget) {
  quiet_gdcm();
  const AbortGuard guard;
  AbortGuard::reading(s.frames.empty() ? std::string("series") : s.frames.front().file + " (or another file of its series)");
  const Frame& f0 = s.frames[L.order.front()];
  const unsigned rows = f0.rows, cols = f0.cols;
  const std::size_t plane = static_cast<std::size_t>(rows) * cols;
  Volume v;
  if (!L.resample) v.hu.resize(plane * L.order.size());
  const DecodedFrames decoded = decode_frames(s, L, rows, cols, L.resample ? nullptr : v.hu.data());
  const std::size_t dropped = exact_duplicates(s, L, decoded, plane);
  if (dropped) warnings.push_back(std::to_string(dropped) + " exact duplicate slice(s) ignored");
  if (decoded.padded) warnings.push_back(std::to_string(decoded.padded) + " padding voxels (PixelPaddingValue) set to air");
  if (lower(s.photometric) == "monochrome1")
    warnings.push_back("MONOCHROME1 CT: the inverted display convention does not change HU and is ignored");

  Geometry& g = v.geom;
  const Vec3 r = f0.row_dir, c = f0.col_dir, n = L.normal;
  g.spacing = {f0.spacing_i, f0.spacing_j, L.nominal_spacing};
  g.direction = {r[0], c[0], n[0], r[1], c[1], n[1], r[2], c[2], n[2]};
  if (L.resample) {
    resample_frames(v, s, L, decoded.at, memory_budget);
    return v;
  }
  g.size = {cols, rows, L.order.size()};
  g.origin = f0.ipp;
  return v;
}

}  // namespace ms::io::dicom

namespace ms::io::dicom {

DicomSource source_of(const Series& series, const Layout& layout) {
  DicomSource src;
  src.study_uid = series.study_uid;
  src.series_uid = series.uid;
  src.frame_of_reference_uid = series.frame_of_reference_uid;
  src.sop_class_uid = series.sop_class;
  src.modality = series.modality;
  for (const std::size_t i : layout.order) {
    const Frame& f = series.frames[i];
    DicomSourceFrame d;
    d.file = f.file;
    d.frame = f.frame;
    d.sop_instance_uid = f.sop_instance_uid;
    d.ipp = f.ipp;
    d.row_dir = f.row_dir;
    d.col_dir = f.col_dir;
    d.spacing_i = f.spacing_i;
    d.spacing_j = f.spacing_j;
    d.rows = f.rows;
    d.cols = f.cols;
    src.frames.push_back(std::move(d));
  }
  if (!src.frames.empty()) src.first_file = src.frames.front().file;
  return src;
}

}  // namespace ms::io::dicom
