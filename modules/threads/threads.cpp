#include "threads/threads.h"

#include <omp.h>
#include <sched.h>

#include <algorithm>
#include <atomic>
#include <thread>

#include <itkMultiThreaderBase.h>
#include <vtkSMPTools.h>

namespace ms::threads {
namespace {

std::atomic<int> g_budget{0};  // 0: not set

}  // namespace

int available_cores() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) {
    const int n = CPU_COUNT(&set);
    if (n > 0) return n;
  }
  return std::max(1u, std::thread::hardware_concurrency());
}

void set_budget(int n) {
  if (n <= 0) n = available_cores();
  g_budget = n;
  omp_set_num_threads(n);
  itk::MultiThreaderBase::SetGlobalMaximumNumberOfThreads(static_cast<itk::ThreadIdType>(std::max(n, 1)));
  itk::MultiThreaderBase::SetGlobalDefaultNumberOfThreads(static_cast<itk::ThreadIdType>(n));
  vtkSMPTools::Initialize(n);
}

int budget() {
  const int n = g_budget;
  return n > 0 ? n : available_cores();
}

std::launch side_task_launch() { return budget() >= 2 ? std::launch::async : std::launch::deferred; }

}  // namespace ms::threads
