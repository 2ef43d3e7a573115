// Process-wide memory set-up for the volume stages (docs/benchmarks.md,
// "Freed memory reused" and "Huge pages"). Call once at start-up, before the
// first large allocation. Results never depend on it; only speed does.
#pragma once

namespace ms {

// glibc only (a no-op elsewhere): large blocks come from the heap and freed
// ones stay there for reuse; the heap's first 1.5 GB are reserved (address
// space only, nothing is touched) and advised for transparent huge pages, so
// a volume-sized array is faulted in 2 MB at a time instead of 4 kB.
void tune_allocator_for_volumes();

}  // namespace ms
