// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/visualization/scene_renderer.h>

#include <X11/Xlib.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace planar_grid {

namespace {

/** \brief Set in the environment of the re-executed program, so that a second failure
 * to find a display ends with an error instead of re-executing forever. */
constexpr const char* UNDER_XVFB_ENV = "PLANAR_GRID_UNDER_XVFB";

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

void
ensureDisplay(int argc, char** argv)
{
  if (hasDisplay())
    return;
  if (std::getenv(UNDER_XVFB_ENV) != nullptr)
    throw Exception(std::string("already re-executed under xvfb-run (") + UNDER_XVFB_ENV
                    + " is set) and still " + NO_DISPLAY_HINT);
  if (argc < 1 || argv == nullptr)
    throw Exception(std::string("ensureDisplay() got no program arguments; ")
                    + NO_DISPLAY_HINT);

  // argv[0] may be a bare name found through PATH or a relative path; the running
  // binary itself is /proc/self/exe.
  std::error_code ec;
  std::string self = std::filesystem::read_symlink("/proc/self/exe", ec).string();
  if (ec || self.empty())
    self = argv[0];

  std::vector<std::string> args{"xvfb-run", "-a", self};
  for (int i = 1; i < argc; ++i)
    args.emplace_back(argv[i]);
  std::vector<char*> exec_argv;
  exec_argv.reserve(args.size() + 1);
  for (auto& arg : args)
    exec_argv.push_back(arg.data());
  exec_argv.push_back(nullptr);

  if (::setenv(UNDER_XVFB_ENV, "1", 1) != 0)
    throw Exception(std::string("cannot set ") + UNDER_XVFB_ENV + ": "
                    + std::strerror(errno) + "; " + NO_DISPLAY_HINT);
  // Whatever was printed so far must not be lost when the process image is replaced.
  std::fflush(stdout);
  std::fflush(stderr);
  ::execvp("xvfb-run", exec_argv.data());
  // Only reached when execvp failed, usually because xvfb-run is not on the PATH.
  const std::string reason = std::strerror(errno);
  ::unsetenv(UNDER_XVFB_ENV);
  throw Exception(std::string(NO_DISPLAY_HINT) + " (cannot run xvfb-run: " + reason
                  + ")");
}

} // namespace planar_grid
