// An X display for VTK's renderer (Debian's VTK renders through X only): the
// user's DISPLAY when it answers, otherwise a private Xvfb started for this
// process and stopped at exit (ENGINEERING.md).
#pragma once

#include <string>

namespace ms::reports {

// True when rendering can proceed; otherwise *why says why not (no DISPLAY
// and no Xvfb installed, Xvfb failed to start, ...). Cheap after the first call.
bool ensure_display(std::string* why);

}  // namespace ms::reports
