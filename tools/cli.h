// SPDX-License-Identifier: BSD-3-Clause
// What every planar_grid_* tool does with its command line: reject unknown arguments,
// and turn an exception into one "name: message" line and a non-zero exit. Header-only,
// private to tools/.
#pragma once

#include <planar_grid/core/exceptions.h>

#include <pcl/console/print.h>

#include <algorithm>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

namespace planar_grid {
namespace cli {

/** \brief Checks that every argument is a known option: one of \a with_value followed
 * by its value, or one of \a switches. A typo is an error, not a default.
 * \param[in] argc, argv the command line
 * \param[in] with_value options that take the next argument as their value
 * \param[in] switches options without a value
 * \throws planar_grid::Exception naming the first unknown argument, or an option whose
 * value is missing */
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
        throw Exception("option " + a + " needs a value");
      ++i;
    } else if (std::find(switches.begin(), switches.end(), a) == switches.end())
      throw Exception("unknown argument '" + a + "' (see --help)");
  }
}

/** \brief Runs a tool's \a run: its return value is the exit status; an exception is
 * printed as "name: message" (pcl::console::print_error) and exits with
 * EXIT_FAILURE.
 * \param[in] name the program name for the message
 * \param[in] run the tool's body
 * \param[in] argc, argv the command line, passed on */
template <typename Run>
int
runMain(const char* name, Run run, int argc, char** argv)
{
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    pcl::console::print_error("%s: %s\n", name, e.what());
  } catch (...) {
    pcl::console::print_error("%s: unknown error\n", name);
  }
  return EXIT_FAILURE;
}

} // namespace cli
} // namespace planar_grid
