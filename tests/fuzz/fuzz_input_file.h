// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

namespace planar_grid {
namespace fuzz {

/** \brief A file in the temporary folder, one per fuzzer process and \a name, that the
 * readers taking a path are given; rewritten for every input and removed at exit.
 * \ingroup fuzz */
class FuzzInputFile {
public:
  explicit FuzzInputFile(const std::string& name) :
      path_((std::filesystem::temp_directory_path()
             / ("planar_grid_fuzz_" + std::to_string(::getpid()) + "_" + name))
              .string())
  {}
  FuzzInputFile(const FuzzInputFile&) = delete;
  FuzzInputFile& operator=(const FuzzInputFile&) = delete;
  ~FuzzInputFile()
  {
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }

  /** \brief Replaces the file's content by \a size bytes at \a data.
   * \return the file's path */
  const std::string& write(const std::uint8_t* data, std::size_t size) const
  {
    std::ofstream out(path_, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    return path_;
  }

private:
  std::string path_;
};

} // namespace fuzz
} // namespace planar_grid
