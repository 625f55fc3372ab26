// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>

#include <filesystem>

namespace planar_grid {

std::uintmax_t
checkInputFile(const std::string& path, const std::string& kind)
{
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec))
    throw IOError(path + ": no such file");
  if (!fs::is_regular_file(path, ec))
    throw IOError(path + ": not a regular file");
  const std::uintmax_t file_size = fs::file_size(path, ec);
  if (ec)
    throw IOError(path + ": cannot read its size: " + ec.message());
  if (file_size == 0)
    throw IOError(path + ": not " + kind + ": the file is empty (0 bytes)");
  return file_size;
}

} // namespace planar_grid
