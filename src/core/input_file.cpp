// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>

#include <filesystem>

namespace planar_grid {

void
checkRegularFile(const std::string& path, const std::string& what)
{
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  const std::string subject = what.empty() ? std::string() : "the " + what + " is ";
  if (!fs::exists(status))
    throw IOError(path + ": " + (what.empty() ? "no such file" : what + " not found"));
  if (fs::is_directory(status))
    throw IOError(path + ": " + subject + "a folder, not a file");
  if (!fs::is_regular_file(status))
    throw IOError(path + ": " + subject
                  + "not a regular file (a device, pipe or socket)");
}

std::uintmax_t
checkInputFile(const std::string& path, const std::string& kind)
{
  namespace fs = std::filesystem;
  std::error_code ec;
  checkRegularFile(path);
  const std::uintmax_t file_size = fs::file_size(path, ec);
  if (ec)
    throw IOError(path + ": cannot read its size: " + ec.message());
  if (file_size == 0)
    throw IOError(path + ": not " + kind + ": the file is empty (0 bytes)");
  return file_size;
}

} // namespace planar_grid
