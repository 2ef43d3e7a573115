// Quality control of one run (docs/qc.md): checks of the result against
// anatomy and against the mandible atlas, each with its value, allowed range
// and the source of that range. A `fail` means the result is likely wrong
// (another bone, a wrong orientation): every output is still written, the
// report opens with the failures and `run` exits with code 8.
#pragma once

#include <string>
#include <vector>

namespace ms::reports {

struct RunSummary;

struct QcCheck {
  std::string name;
  double value = 0;         // NaN: not measurable (e.g. a landmark missing)
  double lo = 0, hi = 0;    // allowed range [lo, hi]
  std::string unit;
  std::string source;       // where the range comes from
  bool passed = true;
  bool fatal = true;        // a failed fatal check fails the run; otherwise it warns
  std::string message;      // what a failure means, for the report
};

struct Qc {
  std::string status = "pass";  // pass | warn | fail
  // On a fail, what most likely explains the failed checks (docs/qc.md,
  // "The cause of a failure"); empty otherwise.
  std::string cause;
  std::vector<QcCheck> checks;
  std::vector<const QcCheck*> failed() const;
};

// Evaluates every check on a finished run's summary.
Qc evaluate_qc(const RunSummary& s);

}  // namespace ms::reports
