// Checked file output (docs/security.md, "Output folder"): every byte written
// is verified, including the final flush, so that a full disk or a vanished
// folder becomes ms::Error(OutputFailed) naming the file, never a crash or a
// silently short file.
#pragma once

#include <string>

namespace ms {

// Writes `bytes` to path + ".partial", then renames it to `path` (readers see
// the old file or the whole new one). Throws ms::Error(OutputFailed).
void write_file_atomic(const std::string& path, const std::string& bytes);

// The whole content of a file ("" when it cannot be opened: for files that
// may legitimately be absent, such as a study's log).
std::string read_file_or_empty(const std::string& path);

}  // namespace ms
