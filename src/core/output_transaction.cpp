// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/output_transaction.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace planar_grid {

namespace fs = std::filesystem;

namespace {

constexpr const char* JOURNAL_MAGIC = "planar_grid output commit 1";

/** fsync(2) of a file or folder; returns 0 or the errno. */
int
syncPath(const fs::path& path, bool folder)
{
  const int fd = ::open(path.c_str(), O_RDONLY | (folder ? O_DIRECTORY : 0));
  if (fd < 0)
    return errno;
  const int result = ::fsync(fd) == 0 ? 0 : errno;
  ::close(fd);
  return result;
}

/** Whether process \a pid no longer exists. */
bool
processGone(long pid)
{
  return ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH;
}

/** The process id a stale file's name ends with after \a prefix, or -1. */
long
trailingPid(const std::string& name, const std::string& prefix)
{
  if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0)
    return -1;
  const std::string digits = name.substr(prefix.size());
  if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos)
    return -1;
  return std::stol(digits);
}

/** Checks that \a name stays inside the output folder and is not one of ours. */
void
checkName(const std::string& folder, const std::string& name)
{
  if (!OutputTransaction::isOutputName(name))
    throw OutputError(folder + ": output name '" + name
                      + "' must be a relative path inside the output folder (no '..', "
                        "not starting with '.planar_grid_')");
}

/** The first folder on the way from \a root to its output \a name that is a symbolic
 * link (empty when none is): a name is checked lexically, but what it resolves to
 * decides where a rename or a removal lands, and through a link that is outside the
 * output folder. */
fs::path
linkOnTheWay(const fs::path& root, const std::string& name)
{
  std::error_code ec;
  fs::path at = root;
  const fs::path parent = fs::path(name).parent_path();
  for (const auto& part : parent) {
    at /= part;
    if (fs::is_symlink(fs::symlink_status(at, ec)))
      return at;
  }
  return {};
}

/** The parsed journal: the staging folder's name, the files to move in and the files
 * to remove. */
struct Journal {
  std::string staging;
  std::vector<std::string> put;
  std::vector<std::string> remove;
};

std::string
journalText(const Journal& journal)
{
  std::ostringstream out;
  out << JOURNAL_MAGIC << "\n"
      << "staging " << journal.staging << "\n";
  for (const auto& name : journal.put)
    out << "put " << name << "\n";
  for (const auto& name : journal.remove)
    out << "remove " << name << "\n";
  std::string text = out.str();
  char crc[32];
  std::snprintf(crc, sizeof(crc), "crc32 0x%08x\n", crc32(text.data(), text.size()));
  return text + crc;
}

Journal
readJournal(const std::string& folder, const fs::path& path)
{
  std::ifstream in(path, std::ios::binary);
  std::ostringstream content;
  content << in.rdbuf();
  if (!in && !in.eof())
    throw OutputError(path.string() + ": cannot read the commit journal");
  const std::string text = content.str();
  const auto corrupt = [&path](const std::string& why) {
    return IOError(path.string() + ": corrupt commit journal (" + why
                   + "); check the folder by hand and remove the file");
  };
  const auto crc_at = text.rfind("crc32 0x");
  if (crc_at == std::string::npos || text.back() != '\n')
    throw corrupt("no checksum line");
  char expected[32];
  std::snprintf(expected, sizeof(expected), "crc32 0x%08x\n",
                crc32(text.data(), crc_at));
  if (text.compare(crc_at, std::string::npos, expected) != 0)
    throw corrupt("checksum mismatch");
  std::istringstream lines(text.substr(0, crc_at));
  std::string line;
  if (!std::getline(lines, line) || line != JOURNAL_MAGIC)
    throw corrupt("bad first line");
  Journal journal;
  while (std::getline(lines, line)) {
    const auto space = line.find(' ');
    const std::string key = line.substr(0, space);
    const std::string value = space == std::string::npos ? "" : line.substr(space + 1);
    if (key == "staging" && trailingPid(value, OutputTransaction::STAGING_PREFIX) >= 0)
      journal.staging = value;
    else if (key == "put" || key == "remove") {
      if (value != OutputTransaction::MANIFEST)
        checkName(folder, value);
      (key == "put" ? journal.put : journal.remove).push_back(value);
    } else
      throw corrupt("unknown line '" + line + "'");
  }
  if (journal.staging.empty())
    throw corrupt("no staging folder");
  return journal;
}

/** The names of the current set (MANIFEST), or none. */
std::vector<std::string>
readManifest(const std::string& folder)
{
  std::vector<std::string> names;
  std::ifstream in(fs::path(folder) / OutputTransaction::MANIFEST);
  std::string line;
  while (std::getline(in, line)) {
    try {
      checkName(folder, line);
      names.push_back(line);
    } catch (const IOError&) {
      // A line edited by hand that names no output of ours is not removed.
    }
  }
  return names;
}

/** Renames the journal's files into place, removes the dropped ones, then the journal
 * and the staging folder. Every step can be repeated: a file already moved is no
 * longer in the staging folder. */
void
applyJournal(const std::string& folder,
             const Journal& journal,
             const std::function<void(const std::string&)>& step)
{
  const fs::path root(folder);
  const fs::path staging = root / journal.staging;
  std::set<fs::path> touched{root};
  std::error_code ec;
  // A folder where a file goes (made after the run checked its names) would stop the
  // renames part way, leaving some outputs new and the others old: refuse before the
  // first rename, and keep the journal for the run after the folder is gone.
  for (const auto& name : journal.put)
    if (fs::exists(staging / name, ec)
        && fs::is_directory(fs::symlink_status(root / name, ec)))
      throw OutputError((root / name).string()
                        + ": is a folder, and the new output cannot replace a folder: "
                          "remove or rename it; the next run into "
                        + folder + " then completes the commit (its journal "
                        + (root / OutputTransaction::JOURNAL).string()
                        + "); nothing was moved");
  for (const auto& name : journal.put) {
    const fs::path link = linkOnTheWay(root, name);
    if (!link.empty())
      throw OutputError((root / name).string() + ": " + link.string()
                        + " is a symbolic link: the output would land outside the "
                          "output folder; nothing was moved there (remove the link; "
                          "the next run into "
                        + folder + " then completes the commit)");
  }
  for (const auto& name : journal.put) {
    const fs::path from = staging / name;
    const fs::path to = root / name;
    if (fs::exists(from, ec)) {
      fs::create_directories(to.parent_path(), ec);
      // ENOENT: another process replaying the same journal moved it first.
      if (std::rename(from.c_str(), to.c_str()) != 0 && errno != ENOENT)
        throw OutputError(to.string() + ": cannot move the new output into place: "
                          + std::strerror(errno) + "; the journal "
                          + (root / OutputTransaction::JOURNAL).string()
                          + " completes the commit on the next run");
      touched.insert(to.parent_path());
    }
    if (step)
      step("put " + name);
  }
  for (const auto& name : journal.remove) {
    // A name through a linked folder is not ours to remove: it lies outside.
    if (linkOnTheWay(root, name).empty())
      fs::remove(root / name, ec);
    if (step)
      step("remove " + name);
  }
  for (const auto& dir : touched)
    syncPath(dir, true);
  fs::remove(root / OutputTransaction::JOURNAL, ec);
  syncPath(root, true);
  fs::remove_all(staging, ec);
}

/** Removes staging folders and temporary files (".<name>.tmp.<pid>") of processes
 * that no longer run, and a staging folder of this process's id left by an earlier
 * process. */
void
removeStale(const std::string& folder)
{
  std::error_code ec;
  const std::string own = std::to_string(static_cast<long>(::getpid()));
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    const long staging_pid = trailingPid(name, OutputTransaction::STAGING_PREFIX);
    if (staging_pid >= 0) {
      if (std::to_string(staging_pid) == own || processGone(staging_pid))
        fs::remove_all(entry.path(), ec);
      continue;
    }
    const auto tmp = name.rfind(".tmp.");
    if (name[0] != '.' || tmp == std::string::npos)
      continue;
    const long pid = trailingPid(name, name.substr(0, tmp + 5));
    if (pid >= 0 && std::to_string(pid) != own && processGone(pid))
      fs::remove(entry.path(), ec);
  }
}

/** Holds SIGINT, SIGTERM and SIGHUP while it lives, process-wide (a handler records
 * them instead of the default action, whichever thread receives them), and raises the
 * first one held when it goes, so that an interrupt does not stop the renames midway.
 * Signals the process ignores stay ignored. */
class HeldSignals {
public:
  HeldSignals()
  {
    held_ = 0;
    for (std::size_t i = 0; i < SIGNALS.size(); ++i) {
      struct sigaction action {};
      action.sa_handler = &HeldSignals::hold;
      sigemptyset(&action.sa_mask);
      ::sigaction(SIGNALS[i], nullptr, &previous_[i]);
      if (previous_[i].sa_handler != SIG_IGN)
        ::sigaction(SIGNALS[i], &action, nullptr);
    }
  }
  ~HeldSignals()
  {
    for (std::size_t i = 0; i < SIGNALS.size(); ++i)
      ::sigaction(SIGNALS[i], &previous_[i], nullptr);
    if (held_ != 0)
      ::raise(held_);
  }
  HeldSignals(const HeldSignals&) = delete;
  HeldSignals& operator=(const HeldSignals&) = delete;

private:
  static void hold(int signal_number)
  {
    if (held_ == 0)
      held_ = signal_number;
  }
  static constexpr std::array<int, 3> SIGNALS{SIGINT, SIGTERM, SIGHUP};
  static volatile sig_atomic_t held_;
  std::array<struct sigaction, 3> previous_{};
};

volatile sig_atomic_t HeldSignals::held_ = 0;

} // namespace

bool
OutputTransaction::isOutputName(const std::string& name)
{
  const fs::path path = fs::path(name).lexically_normal();
  const std::string first = path.empty() ? "" : path.begin()->string();
  return !name.empty() && !path.is_absolute() && first != ".." && first != "."
         && path.has_filename() && name.find('\n') == std::string::npos
         && first.rfind(".planar_grid_", 0) != 0;
}

OutputTransaction::OutputTransaction(std::string folder) : folder_(std::move(folder))
{
  std::error_code ec;
  if (fs::exists(folder_, ec) && !fs::is_directory(folder_, ec))
    throw OutputError(folder_ + ": the output folder is a file, not a folder");
  fs::create_directories(folder_, ec);
  if (ec || !fs::is_directory(folder_))
    throw OutputError(folder_ + ": cannot create the output folder: " + ec.message());
  lock();
  try {
    recover(folder_);
    removeStale(folder_);
    const fs::path staging =
      fs::path(folder_)
      / (STAGING_PREFIX + std::to_string(static_cast<long>(::getpid())));
    if (::mkdir(staging.c_str(), 0755) != 0)
      throw OutputError(folder_ + ": cannot write into the output folder (creating "
                        + staging.filename().string() + "): " + std::strerror(errno));
    staging_ = staging.string();
  } catch (...) {
    // No destructor runs for a constructor that throws: release the lock here.
    ::close(lock_fd_);
    lock_fd_ = -1;
    throw;
  }
}

OutputTransaction::~OutputTransaction()
{
  // After the journal is written its staged files belong to it: the next run moves
  // them into place.
  if (!committed_ && !journal_written_ && !staging_.empty()) {
    std::error_code ec;
    fs::remove_all(staging_, ec);
  }
  // Closing the descriptor releases the lock (as the kernel does when the process
  // dies). The lock file stays: removing it would let a third process lock a new file
  // of the same name while a second one still waits on the old one.
  if (lock_fd_ >= 0)
    ::close(lock_fd_);
}

void
OutputTransaction::lock()
{
  const fs::path path = fs::path(folder_) / LOCK;
  // O_NOFOLLOW: a symbolic link in its place would make the pid land in (and
  // truncate) whatever it points to.
  lock_fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
  if (lock_fd_ < 0 && errno == ELOOP)
    throw OutputError(path.string()
                      + ": is a symbolic link; the lock file is not followed through "
                        "links (remove it)");
  if (lock_fd_ < 0)
    throw OutputError(folder_ + ": cannot write into the output folder (creating "
                      + path.filename().string() + "): " + std::strerror(errno));
  if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    // The holder wrote its process id into the file when it took the lock.
    std::string holder;
    char text[32] = {};
    const ssize_t n = ::pread(lock_fd_, text, sizeof(text) - 1, 0);
    if (n > 0)
      holder.assign(text, static_cast<std::size_t>(n));
    holder.erase(holder.find_last_not_of(" \n") + 1);
    ::close(lock_fd_);
    lock_fd_ = -1;
    if (error == EWOULDBLOCK)
      throw OutputError(
        folder_ + ": the output folder is in use by another run ("
        + (holder.empty() ? std::string("process id unknown") : "process " + holder)
        + " holds " + path.string()
        + "); wait for it to finish or choose another output folder");
    throw OutputError(path.string()
                      + ": cannot lock the output folder: " + std::strerror(error));
  }
  const std::string pid = std::to_string(static_cast<long>(::getpid())) + "\n";
  if (::ftruncate(lock_fd_, 0) != 0
      || ::pwrite(lock_fd_, pid.data(), pid.size(), 0)
           != static_cast<ssize_t>(pid.size())) {
    const std::string reason = std::strerror(errno);
    ::close(lock_fd_);
    lock_fd_ = -1;
    throw OutputError(path.string() + ": cannot write the lock file: " + reason);
  }
}

std::string
OutputTransaction::stagedPath(const std::string& name)
{
  if (committed_)
    throw OutputError(folder_ + ": output '" + name + "' staged after the commit");
  checkName(folder_, name);
  const std::string normal = fs::path(name).lexically_normal().string();
  if (std::find(names_.begin(), names_.end(), normal) == names_.end())
    names_.push_back(normal);
  const fs::path path = fs::path(staging_) / normal;
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  if (ec)
    throw OutputError(finalPath(name) + ": cannot create its staging folder "
                      + path.parent_path().string() + ": " + ec.message());
  return path.string();
}

std::string
OutputTransaction::finalPath(const std::string& name) const
{
  return (fs::path(folder_) / fs::path(name).lexically_normal()).string();
}

std::string
OutputTransaction::write(const std::string& name,
                         const std::function<void(const std::string&)>& write)
{
  const std::string staged = stagedPath(name);
  const std::string final_path = finalPath(name);
  try {
    write(staged);
  } catch (const Exception& e) {
    // The staging folder is an implementation detail: the message names the places
    // in the output folder.
    std::string message = e.what();
    const auto replace_all = [&message](const std::string& from,
                                        const std::string& to) {
      for (auto at = message.find(from); at != std::string::npos;
           at = message.find(from, at + to.size()))
        message.replace(at, from.size(), to);
    };
    replace_all(staged, final_path);
    replace_all(staging_, folder_);
    replace_all("; the previous file, if any, is unchanged", "");
    if (message.find(final_path) == std::string::npos)
      message = final_path + ": " + message;
    throw OutputError(message + "; no output in " + folder_
                      + " was replaced (the previous set is kept)");
  }
  return final_path;
}

void
OutputTransaction::step(const std::string& name) const
{
  if (step_callback_)
    step_callback_(name);
}

void
OutputTransaction::commit()
{
  if (committed_)
    throw OutputError(folder_ + ": the outputs are already committed");
  const fs::path root(folder_);
  const fs::path staging(staging_);

  // The list of the new set travels with it.
  const std::string manifest_path = (staging / MANIFEST).string();
  {
    std::string text;
    for (const auto& name : names_)
      text += name + "\n";
    writeTextFileAtomically(manifest_path, text);
  }

  // Data first: nothing is renamed before every staged byte is on the disk (a
  // delayed-allocation ENOSPC shows up here).
  std::error_code ec;
  for (const auto& name : names_) {
    if (!fs::is_regular_file(staging / name, ec))
      throw OutputError(finalPath(name) + ": the output was not written; no output in "
                        + folder_ + " was replaced");
    if (const int error = syncPath(staging / name, false); error != 0)
      throw OutputError(finalPath(name)
                        + ": cannot write: " + describeWriteError(error, folder_)
                        + "; no output in " + folder_ + " was replaced");
  }
  if (const int error = syncPath(manifest_path, false); error != 0)
    throw OutputError(manifest_path
                      + ": cannot write: " + describeWriteError(error, folder_));
  syncPath(staging, true);
  // Before the commit point, while the previous set can still be kept whole.
  for (const auto& name : names_)
    if (fs::is_directory(fs::symlink_status(root / name, ec)))
      throw OutputError(finalPath(name)
                        + ": is a folder, and the new output cannot replace a folder: "
                          "remove or rename it; no output in "
                        + folder_ + " was replaced");
  step("synced");

  Journal journal;
  journal.staging = staging.filename().string();
  journal.put = names_;
  journal.put.emplace_back(MANIFEST);
  for (const auto& old_name : readManifest(folder_))
    if (std::find(names_.begin(), names_.end(), old_name) == names_.end())
      journal.remove.push_back(old_name);

  const HeldSignals held;
  // The commit point: once the journal is in place the new set wins, whatever stops
  // this process.
  const fs::path journal_path = root / JOURNAL;
  const fs::path journal_tmp =
    root
    / (std::string(JOURNAL) + ".tmp." + std::to_string(static_cast<long>(::getpid())));
  const std::string text = journalText(journal);
  {
    std::ofstream out(journal_tmp, std::ios::binary | std::ios::trunc);
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    out.close();
    const int error = out ? syncPath(journal_tmp, false) : errno;
    if (!out || error != 0) {
      fs::remove(journal_tmp, ec);
      throw OutputError(journal_path.string() + ": cannot write the commit journal: "
                        + describeWriteError(error, folder_) + "; no output in "
                        + folder_ + " was replaced");
    }
  }
  if (std::rename(journal_tmp.c_str(), journal_path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    fs::remove(journal_tmp, ec);
    throw OutputError(journal_path.string() + ": cannot write the commit journal: "
                      + reason + "; no output in " + folder_ + " was replaced");
  }
  journal_written_ = true;
  syncPath(root, true);
  step("journal");

  applyJournal(folder_, journal, step_callback_);
  committed_ = true;
  step("done");
}

void
OutputTransaction::recover(const std::string& folder)
{
  const fs::path journal_path = fs::path(folder) / JOURNAL;
  std::error_code ec;
  if (!fs::exists(journal_path, ec))
    return;
  applyJournal(folder, readJournal(folder, journal_path), nullptr);
}

} // namespace planar_grid
