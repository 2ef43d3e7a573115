// The libraries' own messages (VTK's output window and logger, ITK's output
// window) kept out of the user's terminal (docs/security.md, "Messages"): the
// contract is one error line on stderr, and warnings in log.txt. Once routed,
// every message the libraries print is held here until a command takes it
// (`run` appends them to log.txt as "library: ..." lines).
#pragma once

#include <string>
#include <vector>

namespace ms::liblog {

// Installs the sinks (VTK output window, VTK logger's stderr verbosity off,
// ITK output window). Call once at start-up, before any library runs.
void route_library_messages();

// The messages held so far, oldest first; the store is emptied.
std::vector<std::string> take_library_messages();

}  // namespace ms::liblog
