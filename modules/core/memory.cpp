#include "core/memory.h"

#include <climits>
#include <cstdint>
#include <cstdlib>
#include <sys/resource.h>
#include <unistd.h>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>
#include "core/error.h"

#if defined(__GLIBC__)
#include <malloc.h>
#include <sys/mman.h>
#endif

namespace ms {

// The stages allocate and free volume-sized arrays (64 MB each at 512^2 x
// 300) dozens of times. glibc serves every block above 32 MB from a fresh
// mmap that the kernel zeroes page by page; from the heap, a freed array is
// reused as it is (segment 4.1-4.2 -> 3.3-3.5 s at 512^2 x 300).
// What is still fresh is the heap's growth to its peak: ~136 000 page faults
// per segmentation at 512^2 x 300, a third of its time on a virtual machine
// (3.1-3.6 s; 2.2-2.4 s when the same process segments again). Backed by
// 2 MB pages they are ~500 times fewer. The kernel gives huge pages to
// advised ranges only (transparent_hugepage = madvise, the common default),
// and glibc advises its heap only when asked by an environment tunable
// (glibc.malloc.hugetlb=1), so the heap is grown once here, advised, and
// freed: it stays as the heap's top (below the trim threshold) and every
// later block is carved from it. Untouched, it costs no memory; the kernel
// splits or ignores the advice where huge pages are off or unavailable.
void tune_allocator_for_volumes() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_MAX, 0);              // large blocks from the heap, not one mmap each
  mallopt(M_TRIM_THRESHOLD, INT_MAX);  // freed blocks stay for reuse (returned at exit)
  constexpr std::size_t kReserve = std::size_t{1536} << 20;
  constexpr std::uintptr_t kHuge = std::uintptr_t{2} << 20;
  if (void* p = std::malloc(kReserve)) {
    const auto lo = (reinterpret_cast<std::uintptr_t>(p) + kHuge - 1) & ~(kHuge - 1);
    const auto hi = (reinterpret_cast<std::uintptr_t>(p) + kReserve) & ~(kHuge - 1);
    if (hi > lo) madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
    std::free(p);
  }
#endif
}

}  // namespace ms

// ------------------------------------------------------------ memory budget

namespace ms {
namespace {

// A number of bytes from a cgroup file ("max" or a huge value: no limit).
std::uint64_t read_limit(const std::string& file) {
  std::ifstream in(file);
  std::string s;
  if (!(in >> s) || s == "max") return 0;
  char* end = nullptr;
  const unsigned long long v = std::strtoull(s.c_str(), &end, 10);
  return *end == '\0' ? v : 0;
}

// The smallest memory limit of this process's cgroup and its ancestors
// (v2: memory.max; v1: memory.limit_in_bytes), 0 when none is set.
std::uint64_t cgroup_limit() {
  std::ifstream in("/proc/self/cgroup");
  std::string line;
  std::uint64_t best = 0;
  auto take = [&](std::uint64_t v) {
    if (v > 0 && (best == 0 || v < best)) best = v;
  };
  while (std::getline(in, line)) {
    const auto a = line.find(':'), b = line.find(':', a + 1);
    if (a == std::string::npos || b == std::string::npos) continue;
    const std::string controllers = line.substr(a + 1, b - a - 1);
    std::string rel = line.substr(b + 1);
    const bool v2 = line.compare(0, a, "0") == 0 && controllers.empty();
    const bool v1 = ("," + controllers + ",").find(",memory,") != std::string::npos;
    if (!v2 && !v1) continue;
    const std::string root = v2 ? "/sys/fs/cgroup" : "/sys/fs/cgroup/memory";
    const std::string leaf = v2 ? "/memory.max" : "/memory.limit_in_bytes";
    // Inside a container the path may not exist (cgroup namespace): the root's file is the container's.
    while (true) {
      take(read_limit(root + rel + leaf));
      if (rel.empty() || rel == "/") break;
      rel = rel.substr(0, rel.rfind('/'));
    }
  }
  return best;
}

}  // namespace

std::uint64_t machine_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  std::uint64_t mem = pages > 0 && page > 0 ? static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page) : 0;
  auto cap = [&](std::uint64_t v) {
    if (v > 0 && (mem == 0 || v < mem)) mem = v;
  };
  cap(cgroup_limit());
  rlimit rl{};
  if (::getrlimit(RLIMIT_AS, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY) cap(static_cast<std::uint64_t>(rl.rlim_cur));
  return mem;
}

std::uint64_t default_memory_budget_bytes() {
  constexpr std::uint64_t kFloor = std::uint64_t{256} << 20;  // below this nothing useful runs anyway
  const std::uint64_t mem = machine_memory_bytes();
  if (mem == 0) return 0;
  return std::max(kFloor, static_cast<std::uint64_t>(static_cast<double>(mem) * kMemoryBudgetFraction));
}

std::uint64_t pipeline_peak_bytes(std::uint64_t voxels) {
  const long double b = static_cast<long double>(voxels) * kBytesPerVoxel * kPipelinePeakFactor;
  return b >= 1.8e19L ? UINT64_MAX : static_cast<std::uint64_t>(b);
}

std::uint64_t parse_memory_size(const std::string& text) {
  auto bad = [&]() {
    return Error(ExitCode::Usage, "--max-memory: expected a size such as 2G, 512M or 1.5GiB, got '" + text + "'");
  };
  std::size_t i = 0;
  while (i < text.size() && (std::isdigit(static_cast<unsigned char>(text[i])) || text[i] == '.')) ++i;
  if (i == 0) throw bad();
  char* end = nullptr;
  const std::string num = text.substr(0, i);
  const double v = std::strtod(num.c_str(), &end);
  if (*end != '\0' || !std::isfinite(v)) throw bad();
  std::string unit;
  for (char c : text.substr(i)) unit += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  const std::string units = "KMGT";
  double mult = 1;
  if (!unit.empty() && unit != "B") {
    const auto p = units.find(unit[0]);
    const std::string rest = unit.substr(1);
    if (p == std::string::npos || !(rest.empty() || rest == "B" || rest == "IB")) throw bad();
    mult = std::pow(1024.0, static_cast<double>(p + 1));
  }
  const double bytes = v * mult;
  if (!(bytes >= 1) || bytes >= 1.8e19) throw bad();
  return static_cast<std::uint64_t>(bytes);
}

std::string megabytes(std::uint64_t bytes) {
  std::ostringstream o;
  o << (bytes + 500000) / 1000000 << " MB";
  return o.str();
}

}  // namespace ms
