// Errors that end a run, each with a documented process exit code
// (README "Exit codes"). Messages are one line and name the file and problem.
#pragma once

#include <stdexcept>
#include <string>

namespace ms {

enum class ExitCode : int {
  Ok = 0,
  Internal = 1,        // a bug: please report it
  Usage = 2,           // bad command line
  InputNotFound = 3,   // path missing or unreadable
  InputInvalid = 4,    // not a usable CT: not DICOM, corrupt, wrong modality, bad geometry
  NoMandible = 5,      // segmentation found no mandible / mask empty
  GeometryFailed = 6,  // surface, landmarks or plane could not be computed
  OutputFailed = 7,    // cannot write the output folder
  QcFailed = 8,        // run: the result failed quality control (outputs written; docs/qc.md)
  BatchIncomplete = 9, // batch: at least one study failed (see cohort.csv)
};

class Error : public std::runtime_error {
 public:
  Error(ExitCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  ExitCode code() const { return code_; }

 private:
  ExitCode code_;
};

}  // namespace ms
