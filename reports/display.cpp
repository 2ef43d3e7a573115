#include "reports/display.h"

#include <X11/Xlib.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <vector>

extern char** environ;

namespace ms::reports {
namespace {

bool display_answers(const char* name) {
  if (!name || !*name) return false;
  Display* d = XOpenDisplay(name);
  if (!d) return false;
  XCloseDisplay(d);
  return true;
}

// The private server, stopped when the process exits.
struct PrivateXvfb {
  pid_t pid = -1;
  ~PrivateXvfb() {
    if (pid > 0) {
      kill(pid, SIGTERM);
      waitpid(pid, nullptr, 0);
    }
  }
};
PrivateXvfb g_xvfb;

bool start_xvfb(std::string* why) {
  int fds[2];
  if (pipe(fds) != 0) {
    *why = std::string("pipe: ") + std::strerror(errno);
    return false;
  }
  // -displayfd: Xvfb picks a free display number and writes it to the pipe
  // once it accepts connections.
  const std::string fd = std::to_string(fds[1]);
  std::vector<std::string> args = {"Xvfb", "-displayfd", fd, "-screen", "0", "1280x1024x24", "-nolisten", "tcp", "-noreset"};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addclose(&fa, fds[0]);
  posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, "Xvfb", &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  close(fds[1]);
  if (rc != 0) {
    close(fds[0]);
    *why = "no display and Xvfb is not installed (apt-get install xvfb)";
    return false;
  }
  g_xvfb.pid = pid;
  std::string number;
  pollfd p{fds[0], POLLIN, 0};
  char buf[16];
  while (number.find('\n') == std::string::npos && poll(&p, 1, 10000) > 0) {
    const ssize_t n = read(fds[0], buf, sizeof buf);
    if (n <= 0) break;
    number.append(buf, static_cast<std::size_t>(n));
  }
  close(fds[0]);
  while (!number.empty() && (number.back() == '\n' || number.back() == '\r')) number.pop_back();
  if (number.empty()) {
    *why = "Xvfb did not start within 10 s";
    return false;
  }
  const std::string name = ":" + number;
  if (!display_answers(name.c_str())) {
    *why = "Xvfb started on " + name + " but does not answer";
    return false;
  }
  setenv("DISPLAY", name.c_str(), 1);
  return true;
}

}  // namespace

bool ensure_display(std::string* why) {
  static std::once_flag once;
  static bool ok = false;
  static std::string reason;
  std::call_once(once, [] {
    if (display_answers(std::getenv("DISPLAY"))) {
      ok = true;
      return;
    }
    ok = start_xvfb(&reason);
  });
  if (!ok && why) *why = reason;
  return ok;
}

}  // namespace ms::reports
