#include "core/memory.h"

#include <climits>
#include <cstdint>
#include <cstdlib>

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
