// The thread budget of one `mandisym run` (--threads; `batch --threads-per-job`
// passes it down): every library that starts threads of its own is held to it,
// so that parallel studies share the cores instead of oversubscribing them
// (docs/batch.md, "Jobs and threads").
#pragma once

#include <future>

namespace ms::threads {

// Cores this process may use: the CPU affinity mask (taskset, cgroup cpusets,
// Slurm's --cpus-per-task), else std::thread::hardware_concurrency(); >= 1.
int available_cores();

// Holds OpenMP (omp_set_num_threads), ITK (the global default and maximum
// number of threads of every filter) and VTK's SMP tools (TBB) to n threads;
// n <= 0 means available_cores(). Call once, before any stage runs.
void set_budget(int n);

// The budget set (available_cores() before set_budget is called).
int budget();

// How the pipeline starts work that runs beside the next stage (writing the
// mask and QC figures, the cranial plane, the mirrored atlas fit): on a
// thread of its own when the budget has two or more threads, else deferred to
// the point where its result is needed (one thread, one core).
std::launch side_task_launch();

}  // namespace ms::threads
