// Process-wide memory set-up for the volume stages (docs/benchmarks.md,
// "Freed memory reused" and "Huge pages"), and the memory budget ingest checks
// every declared image size against before anything is decoded or allocated
// (docs/ingest.md, "Memory budget").
#pragma once

#include <cstdint>
#include <string>

namespace ms {

// glibc only (a no-op elsewhere): large blocks come from the heap and freed
// ones stay there for reuse; the heap's first 1.5 GB are reserved (address
// space only, nothing is touched) and advised for transparent huge pages, so
// a volume-sized array is faulted in 2 MB at a time instead of 4 kB.
void tune_allocator_for_volumes();

// Peak resident memory of a whole `mandisym run` per input voxel, in units of
// one float (4 bytes): measured 4.3 (1345 MB RSS for a 512 x 512 x 300 scan,
// 1864 MB for 512 x 512 x 450; docs/ingest.md), rounded up to 5.
constexpr double kPipelinePeakFactor = 5.0;
constexpr std::uint64_t kBytesPerVoxel = 4;  // the pipeline holds the CT as float32

// Share of the machine's memory (see machine_memory_bytes) one run may plan
// for: the rest is left to the system, the page cache and other processes.
constexpr double kMemoryBudgetFraction = 0.75;

// Memory this process can use: physical memory, or less when a cgroup (v2
// memory.max, v1 memory.limit_in_bytes) or RLIMIT_AS says so. 0 if unknown.
std::uint64_t machine_memory_bytes();

// machine_memory_bytes() x kMemoryBudgetFraction (at least 256 MiB; 0 when
// the machine cannot be queried, meaning no limit).
std::uint64_t default_memory_budget_bytes();

// Estimated peak of a run on `voxels` voxels: voxels x 4 B x kPipelinePeakFactor.
std::uint64_t pipeline_peak_bytes(std::uint64_t voxels);

// "2G", "1.5GiB", "512M", "800MB", "300000000" (bytes): K/M/G/T are powers of
// 1024, with or without a trailing B / iB, case-insensitive. Throws
// ms::Error(ExitCode::Usage) on anything else, zero or overflow.
std::uint64_t parse_memory_size(const std::string& text);

// "1345 MB" (10^6 bytes), for one-line messages.
std::string megabytes(std::uint64_t bytes);

}  // namespace ms
