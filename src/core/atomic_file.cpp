// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>

#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace planar_grid {

std::string
describeWriteError(int error_number, const std::string& folder)
{
  if (error_number == EFBIG) {
    std::string text = std::strerror(EFBIG);
    rlimit limit{};
    if (::getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY)
      text += " (over the process's file size limit, ulimit -f: "
              + std::to_string(static_cast<unsigned long long>(limit.rlim_cur))
              + " bytes)";
    return text;
  }
  if (error_number == ENOSPC || error_number == EDQUOT)
    return std::string(std::strerror(error_number)) + " (the disk of " + folder
           + " is full)";
  if (error_number != 0)
    return std::strerror(error_number);
  // The writer failed without an errno (e.g. posix_fallocate() returns its error):
  // look at what usually makes a write fail.
  struct statvfs fs_info {};
  if (::statvfs(folder.c_str(), &fs_info) == 0 && fs_info.f_blocks > 0
      && (::geteuid() == 0 ? fs_info.f_bfree : fs_info.f_bavail) == 0)
    return std::string(std::strerror(ENOSPC)) + " (the disk of " + folder + " is full)";
  rlimit limit{};
  if (::getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY)
    return "the writer failed; the process's file size limit (ulimit -f) is "
           + std::to_string(static_cast<unsigned long long>(limit.rlim_cur)) + " bytes";
  return "the writer reported an error";
}

namespace {

/** \a error_number when it is one a failed open(2) or write(2) gives, else 0: a
 * library writer may print its own message after the failure, and that leaves errno
 * set by an unrelated call (ENOTTY from isatty()). */
int
writeErrno(int error_number)
{
  switch (error_number) {
    case ENOSPC:
    case EDQUOT:
    case EFBIG:
    case EIO:
    case EROFS:
    case EACCES:
    case EPERM:
    case ENOENT:
    case ENOTDIR:
    case EISDIR:
    case ENAMETOOLONG:
    case EMFILE:
    case ENFILE:
      return error_number;
    default:
      return 0;
  }
}

/** The error a writer that reported success still met, or 0: the writers of PCL's PLY
 * files and OctoMap's trees do not check their streams, so a full disk leaves a short
 * file and errno set by the failed write(2); a file as long as the process's file size
 * limit was cut there. */
int
hiddenWriteError(int errno_after_write, const std::string& temporary)
{
  if (errno_after_write == ENOSPC || errno_after_write == EDQUOT
      || errno_after_write == EFBIG || errno_after_write == EIO)
    return errno_after_write;
  rlimit limit{};
  struct stat info {};
  if (::getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY
      && ::stat(temporary.c_str(), &info) == 0
      && static_cast<rlim_t>(info.st_size) >= limit.rlim_cur)
    return EFBIG;
  return 0;
}

} // namespace

void
writeFileAtomically(const std::string& path,
                    const std::function<bool(const std::string&)>& write)
{
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw OutputError(path + ": cannot write: folder " + dir.string()
                      + " does not exist");
  if (fs::is_directory(target, ec))
    throw OutputError(path
                      + ": cannot write: it is a folder, and a file cannot replace "
                        "a folder; give a file name");
  // Same folder as the target so that rename() is atomic on POSIX file systems.
  const fs::path tmp = dir
                       / ("." + target.filename().string() + ".tmp."
                          + std::to_string(static_cast<long>(::getpid())));
  bool ok = false;
  errno = 0;
  try {
    ok = write(tmp.string());
  } catch (const Exception&) {
    fs::remove(tmp, ec);
    throw;
  } catch (const std::runtime_error& e) {
    // A library writer's own exception (pcl::PCDWriter throws pcl::IOException when
    // it cannot allocate the file) names neither the file nor the cause.
    const int write_errno = writeErrno(errno);
    fs::remove(tmp, ec);
    throw OutputError(path + ": cannot write: "
                      + describeWriteError(write_errno, dir.string()) + " (" + e.what()
                      + "); the previous file, if any, is unchanged");
  } catch (...) {
    fs::remove(tmp, ec);
    throw;
  }
  const int write_errno = writeErrno(errno);
  const bool written = fs::exists(tmp, ec);
  const int hidden = ok && written ? hiddenWriteError(write_errno, tmp.string()) : 0;
  if (!ok || !written || hidden != 0) {
    const std::string cause =
      !written && ok
        ? std::string("the writer created no file")
        : describeWriteError(hidden != 0 ? hidden : write_errno, dir.string());
    fs::remove(tmp, ec);
    throw OutputError(path + ": cannot write: " + cause
                      + "; the previous file, if any, is unchanged");
  }
  if (std::rename(tmp.c_str(), target.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    fs::remove(tmp, ec);
    throw OutputError(path
                      + ": cannot rename the temporary file into place: " + reason);
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
