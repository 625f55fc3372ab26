// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace planar_grid {

void
writeFileAtomically(const std::string& path,
                    const std::function<bool(const std::string&)>& write)
{
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw IOError(path + ": cannot write: folder " + dir.string() + " does not exist");
  // Same folder as the target so that rename() is atomic on POSIX file systems.
  const fs::path tmp = dir
                       / ("." + target.filename().string() + ".tmp."
                          + std::to_string(static_cast<long>(::getpid())));
  bool ok = false;
  try {
    ok = write(tmp.string());
  } catch (...) {
    fs::remove(tmp, ec);
    throw;
  }
  if (!ok || !fs::exists(tmp, ec)) {
    fs::remove(tmp, ec);
    throw IOError(path + ": writing failed; the previous file, if any, is unchanged");
  }
  if (std::rename(tmp.c_str(), target.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    fs::remove(tmp, ec);
    throw IOError(path + ": cannot rename the temporary file into place: " + reason);
  }
}

void
writeTextFileAtomically(const std::string& path, const std::string& content)
{
  writeFileAtomically(path, [&content](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << content;
    out.flush();
    return static_cast<bool>(out);
  });
}

} // namespace planar_grid
