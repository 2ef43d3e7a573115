// The run's thread budget reaches OpenMP, ITK and VTK (threads/threads.h).
#include "threads/threads.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <itkMultiThreaderBase.h>
#include <vtkSMPTools.h>

namespace {

TEST(ThreadBudget, HoldsOpenMpItkAndVtkToTheBudget) {
  for (int n : {1, 3, 2}) {
    ms::threads::set_budget(n);
    EXPECT_EQ(ms::threads::budget(), n);
    EXPECT_EQ(omp_get_max_threads(), n);
    EXPECT_EQ(static_cast<int>(itk::MultiThreaderBase::GetGlobalDefaultNumberOfThreads()), n);
    EXPECT_LE(static_cast<int>(itk::MultiThreaderBase::GetGlobalMaximumNumberOfThreads()), n);
    EXPECT_EQ(vtkSMPTools::GetEstimatedNumberOfThreads(), n);
    int seen = 0;
#pragma omp parallel
    {
#pragma omp single
      seen = omp_get_num_threads();
    }
    EXPECT_EQ(seen, n);
  }
}

TEST(ThreadBudget, ZeroMeansTheCoresThisProcessMayUse) {
  ms::threads::set_budget(0);
  EXPECT_EQ(ms::threads::budget(), ms::threads::available_cores());
  EXPECT_GE(ms::threads::available_cores(), 1);
}

TEST(ThreadBudget, SideTasksRunOnTheirOwnThreadOnlyWithTwoOrMore) {
  ms::threads::set_budget(1);
  EXPECT_EQ(ms::threads::side_task_launch(), std::launch::deferred);
  ms::threads::set_budget(2);
  EXPECT_EQ(ms::threads::side_task_launch(), std::launch::async);
}

}  // namespace
