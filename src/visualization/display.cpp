// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/visualization/scene_renderer.h>

#include <X11/Xlib.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace planar_grid {

namespace {

/** \brief What to do when there is no display, for every message below. */
constexpr const char* NO_DISPLAY_HINT =
  "no X display: VTK 9.1 from Debian renders offscreen only through an X server; "
  "install xvfb (apt-get install xvfb) and run under `xvfb-run -a <command>`";

} // namespace

bool
hasDisplay()
{
  /* One connection, opened on the first successful check and kept until exit. An X
   * server (Xvfb as started by xvfb-run, too) resets when its last client disconnects
   * and refuses connections meanwhile; with a check that opened and closed its own
   * connection, VTK's connection right after it could hit that reset and VTK aborts.
   * Keeping ours open means the server never resets under us. */
  struct KeptConnection {
    std::mutex mutex;
    Display* display{nullptr};
    std::string name;
    ~KeptConnection()
    {
      if (display != nullptr)
        XCloseDisplay(display);
    }
  };
  static KeptConnection kept;

  const char* display_env = std::getenv("DISPLAY");
  if (display_env == nullptr || display_env[0] == '\0')
    return false;
  const std::string name(display_env);
  std::lock_guard<std::mutex> lock(kept.mutex);
  if (kept.display != nullptr && kept.name == name)
    return true;
  if (kept.display != nullptr) { // DISPLAY changed since the last check
    XCloseDisplay(kept.display);
    kept.display = nullptr;
  }
  // XOpenDisplay() returns nullptr (it does not abort) when the server does not
  // answer; a few tries ride out a server that is just resetting.
  constexpr int ATTEMPTS = 3;
  for (int attempt = 0; attempt < ATTEMPTS && kept.display == nullptr; ++attempt) {
    if (attempt > 0)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    kept.display = XOpenDisplay(name.c_str());
  }
  if (kept.display == nullptr)
    return false;
  kept.name = name;
  return true;
}

namespace {

/** Starts `Xvfb -displayfd` as a child of this process and returns its display name
 * (":N", the number Xvfb picked among the free ones and wrote to the pipe once it
 * accepts connections). The server gets SIGTERM when the thread that started it
 * ends: call from the main thread. */
std::string
startXvfb()
{
  int ready[2];
  if (::pipe2(ready, O_CLOEXEC) != 0)
    throw Exception(std::string(NO_DISPLAY_HINT)
                    + " (cannot create a pipe for Xvfb: " + std::strerror(errno) + ")");
  // Everything the child needs is prepared before fork(): between fork() and exec()
  // a multi-threaded process may only make async-signal-safe calls.
  const pid_t parent = ::getpid();
  const int child_fd = 3;
  const std::string fd_text = std::to_string(child_fd);
  const pid_t pid = ::fork();
  if (pid == 0) {
    // Xvfb dies with this process, even on SIGKILL; and not at all if the parent is
    // already gone.
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (::getppid() != parent)
      ::_exit(127);
    // The pipe's write end at fd 3, kept across exec; Xvfb's messages go nowhere.
    if (::dup2(ready[1], child_fd) != child_fd)
      ::_exit(127);
    const int null_fd = ::open("/dev/null", O_RDWR);
    if (null_fd >= 0) {
      ::dup2(null_fd, STDIN_FILENO);
      ::dup2(null_fd, STDOUT_FILENO);
      ::dup2(null_fd, STDERR_FILENO);
    }
    ::execlp("Xvfb", "Xvfb", "-displayfd", fd_text.c_str(), "-screen", "0",
             "1280x1024x24", "-nolisten", "tcp", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  const int fork_error = errno;
  ::close(ready[1]);
  if (pid < 0) {
    ::close(ready[0]);
    throw Exception(std::string(NO_DISPLAY_HINT)
                    + " (cannot start Xvfb: " + std::strerror(fork_error) + ")");
  }
  // The display number and a newline, or end of file when Xvfb did not start.
  std::string number;
  char c = 0;
  ssize_t n = 0;
  while ((n = ::read(ready[0], &c, 1)) == 1 || (n < 0 && errno == EINTR))
    if (n == 1) {
      if (c == '\n')
        break;
      number.push_back(c);
    }
  ::close(ready[0]);
  if (number.empty() || number.find_first_not_of("0123456789") != std::string::npos) {
    int status = 0;
    ::waitpid(pid, &status, 0);
    throw Exception(std::string(NO_DISPLAY_HINT) + " (Xvfb "
                    + (WIFEXITED(status) && WEXITSTATUS(status) == 127
                         ? "is not installed or could not be run"
                         : "did not start")
                    + ")");
  }
  return ":" + number;
}

} // namespace

void
ensureDisplay(int /*argc*/, char** /*argv*/)
{
  if (hasDisplay())
    return;
  // The server is this process's child, not a wrapper around it (xvfb-run): the exit
  // code is the program's own, and the kernel stops the server when the program ends,
  // however it ends (PR_SET_PDEATHSIG), so that none is left behind.
  const std::string display = startXvfb();
  if (::setenv("DISPLAY", display.c_str(), 1) != 0)
    throw Exception(std::string("cannot set DISPLAY: ") + std::strerror(errno));
  if (!hasDisplay())
    throw Exception("Xvfb started on display " + display + " but does not answer; "
                    + NO_DISPLAY_HINT);
}

} // namespace planar_grid
