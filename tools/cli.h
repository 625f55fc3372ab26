// SPDX-License-Identifier: BSD-3-Clause
// What every planar_grid_* tool does with its command line: print its version for
// --version, reject unknown arguments, and turn an exception into one "name: message"
// line and a non-zero exit. Header-only, private to tools/.
#pragma once

#include <planar_grid/core/exceptions.h>
#include <planar_grid/version.h>

#include <pcl/console/print.h>

#include <malloc.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

namespace planar_grid {
namespace cli {

/** \brief A wrong command line: an unknown option, a missing or malformed value. */
class UsageError : public Exception {
public:
  /** \param[in] what the message; it names the argument and what was expected */
  explicit UsageError(const std::string& what) : Exception(what) {}
};

/** \brief Checks that every argument is a known option: one of \a with_value followed
 * by its value, or one of \a switches. A typo is an error, not a default.
 * \param[in] argc, argv the command line
 * \param[in] with_value options that take the next argument as their value
 * \param[in] switches options without a value
 * \throws planar_grid::cli::UsageError naming the first unknown argument, or an option
 * whose value is missing */
inline void
checkArguments(int argc,
               char** argv,
               const std::vector<std::string>& with_value,
               const std::vector<std::string>& switches)
{
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (std::find(with_value.begin(), with_value.end(), a) != with_value.end()) {
      if (i + 1 >= argc)
        throw UsageError("option " + a + " needs a value");
      ++i;
    } else if (std::find(switches.begin(), switches.end(), a) == switches.end())
      throw UsageError("unknown argument '" + a + "' (see --help)");
  }
}

/** \brief Keeps freed memory in the process for the next frame instead of returning
 * it to the kernel. The stages allocate and free images, pyramids and clouds of tens of
 * MB every frame; with glibc's defaults those come from fresh mmap() pages each time,
 * and the page faults cost a fifth of the pipeline's CPU time (perf, Karlsruhe). Blocks
 * up to 32 MiB (glibc's largest mmap threshold) come from the heap, and the heap is
 * trimmed only when 1 GiB lies free at its top. Results are unchanged; the peak
 * resident memory grows by what one frame frees (about 20 MB in the main job). Source:
 * glibc mallopt(M_MMAP_THRESHOLD, M_TRIM_THRESHOLD). */
inline void
keepFreedMemory()
{
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 1024 * 1024 * 1024);
}

/** \brief Ends keepFreedMemory(): from here on blocks of 128 KiB and more are mapped on
 * their own and returned to the kernel when freed, and the heap is trimmed at 128 KiB
 * (glibc's defaults), and what the frames left free is returned now. For the outputs
 * after the frames: the OctoMap export and each offscreen snapshot allocate and free
 * hundreds of MB once, and kept, those would add up in the peak resident memory.
 * Source: glibc mallopt(M_MMAP_THRESHOLD, M_TRIM_THRESHOLD), malloc_trim(). */
inline void
releaseFreedMemory()
{
  mallopt(M_MMAP_THRESHOLD, 128 * 1024);
  mallopt(M_TRIM_THRESHOLD, 128 * 1024);
  malloc_trim(0);
}

/** \brief Lets Mesa's software renderer (llvmpipe, the offscreen renderer of a machine
 * without a GPU) rasterise each scene as soon as it is binned, in the calling thread,
 * instead of queueing binned scenes for its rasteriser threads. With threads, a map
 * snapshot of a street (about 350,000 instanced boxes) holds up to six binned scenes
 * of about 34 MB each at once; without, one: the viewer's map snapshot of the main job
 * peaks at 299 MB instead of 336-448 MB, with the same PNG, about a second slower. Call
 * it before the first render window is created (Mesa reads the setting once). A value
 * the user set is kept; a GPU driver ignores it. Source: Mesa's LP_NUM_THREADS. */
inline void
preferLowMemorySoftwareRendering()
{
  setenv("LP_NUM_THREADS", "0", 0);
}

/** \brief True when the command line asks for the version: --version anywhere (as the
 * GNU tools, whatever else is given). */
inline bool
wantsVersion(int argc, char** argv)
{
  for (int i = 1; i < argc; ++i)
    if (std::strcmp(argv[i], "--version") == 0)
      return true;
  return false;
}

/** \brief Prints "<name> <version>" (the project's version, from CMake) on stdout. */
inline void
printVersion(const char* name)
{
  std::printf("%s %s\n", name, PLANAR_GRID_VERSION_STRING);
}

/** \brief Runs a tool's \a run after keepFreedMemory(): its return value is the exit
 * status; an exception is printed as "name: message" (pcl::console::print_error) and
 * exits with \a exit_status(exception), EXIT_FAILURE for an exception not derived from
 * std::exception. With --version it prints the name and version and exits with
 * EXIT_SUCCESS without running \a run. A non-empty NO_COLOR in the environment turns
 * the messages' colours off.
 * \param[in] name the program name for the message
 * \param[in] run the tool's body
 * \param[in] argc, argv the command line, passed on
 * \param[in] exit_status the exit status of an exception (int(const std::exception&))
 */
template <typename Run, typename ExitStatus>
int
runMain(const char* name, Run run, int argc, char** argv, ExitStatus exit_status)
{
  if (wantsVersion(argc, argv)) {
    printVersion(name);
    return EXIT_SUCCESS;
  }
  keepFreedMemory();
  if (const char* no_color = std::getenv("NO_COLOR"); no_color && *no_color != '\0') {
    // https://no-color.org: a non-empty NO_COLOR turns colour off.
    pcl::console::enableColoredOutput(stdout, false);
    pcl::console::enableColoredOutput(stderr, false);
  }
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    pcl::console::print_error("%s: %s\n", name, e.what());
    return exit_status(e);
  } catch (...) {
    pcl::console::print_error("%s: unknown error\n", name);
  }
  return EXIT_FAILURE;
}

/** \brief As runMain() above, with EXIT_FAILURE for every exception. */
template <typename Run>
int
runMain(const char* name, Run run, int argc, char** argv)
{
  return runMain(name, run, argc, argv,
                 [](const std::exception&) { return EXIT_FAILURE; });
}

} // namespace cli
} // namespace planar_grid
