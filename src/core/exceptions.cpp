// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>

namespace planar_grid {

namespace {
std::string
formatLocation(const std::string& file,
               int line,
               int column,
               const std::string& message)
{
  std::string where = file.empty() ? std::string("<yaml>") : file;
  if (line > 0) {
    where += ":" + std::to_string(line);
    if (column > 0)
      where += ":" + std::to_string(column);
  }
  return where + ": " + message;
}
} // namespace

ConfigError::ConfigError(const std::string& file,
                         int line,
                         int column,
                         const std::string& message) :
    Exception(formatLocation(file, line, column, message)),
    file_(file), line_(line), column_(column), message_(message)
{}

} // namespace planar_grid
