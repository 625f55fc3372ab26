// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_pipeline replaces its outputs as one set: with the disk full (a file size
// limit) or killed while it writes them, the output folder holds exactly the previous
// outputs or the new ones, byte for byte, and a failed write is an error naming the
// file and the cause.
#include <planar_grid/core/output_transaction.h>

#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/inotify.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/statvfs.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include "karlsruhe_job.h"

namespace fs = std::filesystem;

namespace {

/** Karlsruhe frames 10-12 through the paper pipeline with the map; every output but
 * the snapshots, or (\a mesh_only) the mesh and the report only. */
std::string
commitJobConfig(const fs::path& output, bool mesh_only = false)
{
  return planar_grid::test::karlsruheJob(
    3, output,
    mesh_only ? "  cloud: \"\"\n  planes: \"\"\n  map: \"\"\n  map_octomap: \"\"\n"
                "  trajectory: \"\"\n"
              : "");
}

/** Starts planar_grid_pipeline with \a args, its output in \a log; with \a
 * file_size_limit > 0 under that RLIMIT_FSIZE (bytes), ignoring SIGXFSZ so that a write
 * past it fails with EFBIG as a write to a full disk fails with ENOSPC. */
pid_t
start(const std::vector<std::string>& args,
      const fs::path& log,
      rlim_t file_size_limit = 0)
{
  // Nothing buffered that the child would write again.
  std::cout.flush();
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::vector<char*> argv;
    static std::string tool = PLANAR_GRID_PIPELINE_TOOL;
    argv.push_back(tool.data());
    std::vector<std::string> copies = args;
    for (auto& a : copies)
      argv.push_back(a.data());
    argv.push_back(nullptr);
    // One open file for both streams, so that neither overwrites the other.
    std::freopen(log.c_str(), "w", stdout);
    ::dup2(STDOUT_FILENO, STDERR_FILENO);
    if (file_size_limit > 0) {
      ::signal(SIGXFSZ, SIG_IGN); // kept across exec
      const rlimit limit{file_size_limit, file_size_limit};
      ::setrlimit(RLIMIT_FSIZE, &limit);
    }
    ::execv(tool.c_str(), argv.data());
    ::_exit(127);
  }
  return pid;
}

int
exitCode(pid_t pid)
{
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string
fileBytes(const fs::path& file)
{
  std::ifstream in(file.string(), std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in),
                     std::istreambuf_iterator<char>());
}

/** Every regular file under \a folder (relative name -> bytes). */
std::map<std::string, std::string>
contents(const fs::path& folder)
{
  std::map<std::string, std::string> files;
  // The lock file belongs to the folder (it holds the last run's process id), not to
  // an output set.
  for (const auto& e : fs::recursive_directory_iterator(folder))
    if (e.is_regular_file()
        && e.path().filename() != planar_grid::OutputTransaction::LOCK)
      files[fs::relative(e.path(), folder).string()] = fileBytes(e.path());
  return files;
}

/** contents() without the staging folders a killed run leaves (not outputs; the next
 * run removes them). */
std::map<std::string, std::string>
outputs(const fs::path& folder)
{
  auto files = contents(folder);
  for (auto it = files.begin(); it != files.end();)
    it = it->first.rfind(planar_grid::OutputTransaction::STAGING_PREFIX, 0) == 0
           ? files.erase(it)
           : std::next(it);
  return files;
}

/** Whether \a files are the outputs \a reference of another run (into another folder,
 * or at another time): the same names, the same bytes but for report.json, whose
 * timings (and paths) differ. */
bool
sameOutputs(const std::map<std::string, std::string>& files,
            const std::map<std::string, std::string>& reference)
{
  if (files.size() != reference.size())
    return false;
  for (const auto& [name, bytes] : reference) {
    const auto it = files.find(name);
    if (it == files.end() || (name != "report.json" && it->second != bytes))
      return false;
  }
  return true;
}

class OutputCommitTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    dir_ = fs::temp_directory_path()
           / ("planar_grid_output_commit_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    out_ = dir_ / "out";
    yaml_ = dir_ / "run.yaml";
    std::ofstream(yaml_) << commitJobConfig(out_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  /** Runs the tool on frames \a frames into out_; returns the exit code. */
  int run(const std::string& frames, rlim_t file_size_limit = 0)
  {
    return exitCode(start(
      {"--config", yaml_.string(), "--frames", frames, "--no-snapshot", "--sequential"},
      log_, file_size_limit));
  }

  fs::path dir_, out_, yaml_,
    log_{fs::temp_directory_path()
         / ("planar_grid_output_commit_" + std::to_string(::getpid()) + ".log")};
};

TEST_F(OutputCommitTest, FullDiskKeepsTheOldOutputsAndNamesTheFile)
{
  ASSERT_EQ(run("0:1"), 0) << fileBytes(log_);
  const auto old_set = contents(out_);
  ASSERT_GE(old_set.size(), 7u); // 6 outputs and the list of the set
  const std::size_t mesh_bytes = old_set.at("map_cuboids.ply").size();
  ASSERT_GT(mesh_bytes, 10000u);

  // Two frames need more room than there is: a write fails, the run exits 5 (an
  // output error) naming the output (its place in the folder, not the staging copy)
  // and the cause.
  const rlim_t limit = mesh_bytes / 2;
  EXPECT_EQ(run("0:2", limit), 5);
  std::string log = fileBytes(log_);
  EXPECT_NE(log.find(out_.string() + "/"), std::string::npos) << log;
  EXPECT_NE(log.find(": cannot write: "), std::string::npos) << log;
  EXPECT_NE(log.find("file size limit"), std::string::npos) << log;
  EXPECT_EQ(log.find(planar_grid::OutputTransaction::STAGING_PREFIX), std::string::npos)
    << log;
  EXPECT_EQ(contents(out_), old_set); // byte for byte, nothing left over

  // PCL's PLY writer does not check its stream: its short file is caught all the same.
  std::ofstream(yaml_) << commitJobConfig(out_, true);
  EXPECT_EQ(run("0:2", limit), 5);
  log = fileBytes(log_);
  EXPECT_NE(log.find(out_.string() + "/map_cuboids.ply: cannot write: File too large"),
            std::string::npos)
    << log;
  EXPECT_EQ(contents(out_), old_set);
  fs::remove(log_);
}

TEST_F(OutputCommitTest, RealFullDiskKeepsTheOldOutputs)
{
  // A small tmpfs as the output folder's disk: needs root (mount(2)).
  const fs::path disk = dir_ / "disk";
  fs::create_directories(disk);
  if (::geteuid() != 0 || ::mount("tmpfs", disk.c_str(), "tmpfs", 0, "size=64m") != 0)
    GTEST_SKIP() << "mounting a tmpfs needs root";
  struct Unmount {
    fs::path path;
    ~Unmount() { ::umount2(path.c_str(), MNT_DETACH); }
  } unmount{disk};
  const fs::path out = disk / "out";
  std::ofstream(yaml_) << commitJobConfig(out);
  ASSERT_EQ(run("0:1"), 0) << fileBytes(log_);
  const auto old_set = contents(out);
  // Room for the old set and half of it again: the 2-frame set does not fit beside it.
  struct statvfs info {};
  ASSERT_EQ(::statvfs(disk.c_str(), &info), 0);
  const auto used_kib = (info.f_blocks - info.f_bfree) * info.f_frsize / 1024;
  const std::string size = "size=" + std::to_string(used_kib * 3 / 2) + "k";
  ASSERT_EQ(::mount("tmpfs", disk.c_str(), "tmpfs", MS_REMOUNT, size.c_str()), 0);

  EXPECT_EQ(run("0:2"), 5);
  const std::string log = fileBytes(log_);
  EXPECT_NE(log.find(out.string() + "/"), std::string::npos) << log;
  EXPECT_NE(log.find(": cannot write: No space left on device (the disk of "
                     + out.string() + " is full)"),
            std::string::npos)
    << log;
  EXPECT_EQ(log.find(planar_grid::OutputTransaction::STAGING_PREFIX), std::string::npos)
    << log;
  EXPECT_EQ(contents(out), old_set); // byte for byte, the staging folder removed
  fs::remove(log_);
}

TEST_F(OutputCommitTest, KilledWhileWritingOutputsLeavesTheOldOrTheNewSet)
{
  // The new set (frame 11's), from a run never killed, in another folder; the old set
  // is frame 10's. Each run costs seconds under the sanitizers, so each set is one
  // frame's.
  const fs::path reference = dir_ / "reference";
  std::ofstream(dir_ / "reference.yaml") << commitJobConfig(reference);
  ASSERT_EQ(exitCode(start({"--config", (dir_ / "reference.yaml").string(), "--frames",
                            "1:2", "--no-snapshot", "--sequential"},
                           log_)),
            0)
    << fileBytes(log_);
  const auto new_set = contents(reference);
  // The old set.
  ASSERT_EQ(run("0:1"), 0) << fileBytes(log_);
  auto old_set = contents(out_);
  ASSERT_FALSE(sameOutputs(old_set, new_set));

  // Kill (SIGKILL) the frame 11 run into the same folder the moment inotify reports its
  // k-th output staged, or its commit journal, then let the next transaction on the
  // folder finish or drop the commit.
  int old_seen = 0, new_seen = 0;
  for (int kill_at : {1, 3, 6, -1}) {
    SCOPED_TRACE("kill at " + std::to_string(kill_at));
    const int watch = ::inotify_init1(IN_NONBLOCK);
    ASSERT_GE(watch, 0);
    ::inotify_add_watch(watch, out_.c_str(), IN_CREATE | IN_MOVED_TO);
    const pid_t pid = start(
      {"--config", yaml_.string(), "--frames", "1:2", "--no-snapshot", "--sequential"},
      log_);
    int staged = 0, status = 0;
    bool killed = false, exited = false;
    while (!killed && !exited) {
      pollfd fd{watch, POLLIN, 0};
      if (::poll(&fd, 1, 100) > 0) {
        alignas(inotify_event) char buffer[4096];
        const ssize_t n = ::read(watch, buffer, sizeof(buffer));
        for (ssize_t at = 0; at < n && !killed;) {
          const auto* event = reinterpret_cast<const inotify_event*>(buffer + at);
          const std::string name = event->len > 0 ? event->name : "";
          if ((event->mask & IN_ISDIR)
              && name.rfind(planar_grid::OutputTransaction::STAGING_PREFIX, 0) == 0)
            ::inotify_add_watch(watch, (out_ / name).c_str(), IN_MOVED_TO);
          else if ((event->mask & IN_MOVED_TO) && name.rfind('.', 0) != 0)
            killed = ++staged == kill_at;
          else if ((event->mask & IN_MOVED_TO)
                   && name == planar_grid::OutputTransaction::JOURNAL)
            killed = kill_at < 0;
          at += static_cast<ssize_t>(sizeof(inotify_event) + event->len);
        }
      }
      if (killed)
        ::kill(pid, SIGKILL);
      exited = !killed && ::waitpid(pid, &status, WNOHANG) == pid;
    }
    if (killed)
      ::waitpid(pid, &status, 0);
    ::close(watch);
    planar_grid::OutputTransaction::recover(out_.string());
    const auto after = outputs(out_);
    const bool is_old = after == old_set, is_new = sameOutputs(after, new_set);
    EXPECT_TRUE(is_old || is_new) << after.size() << " files, " << staged << " staged";
    old_seen += is_old;
    new_seen += is_new;
    // Back to the old set for the next kill: the run also removes the killed run's
    // staging folder (contents() would show it).
    ASSERT_EQ(run("0:1"), 0) << fileBytes(log_);
    const auto again = contents(out_);
    ASSERT_TRUE(sameOutputs(again, old_set));
    old_set = again;
  }
  // Killed at a staged output, the old set stays whatever the timing.
  EXPECT_GE(old_seen, 1);
  std::cout << "[          ] kills that left the old set: " << old_seen
            << ", the new set: " << new_seen << std::endl;

  // The frame 11 run, not killed, commits its set over the old one.
  ASSERT_EQ(exitCode(start({"--config", yaml_.string(), "--frames", "1:2",
                            "--no-snapshot", "--sequential"},
                           log_)),
            0);
  EXPECT_TRUE(sameOutputs(contents(out_), new_set));
  fs::remove(log_);
}

} // namespace

TEST_F(OutputCommitTest, StopSignalEndsTheRunAfterAFrameAndKeepsTheOldOutputs)
{
  ASSERT_EQ(run("0:1"), 0) << fileBytes(log_);
  const auto old_set = contents(out_);
  ASSERT_GE(old_set.size(), 7u);

  // Eight frames; the signal comes once the first is mapped (the tool prints a line
  // per frame when its output is not a terminal), so that frames are still to come.
  std::ofstream(yaml_) << planar_grid::test::karlsruheJob(8, out_, "");
  for (const int signal : {SIGINT, SIGTERM}) {
    SCOPED_TRACE(signal == SIGINT ? "SIGINT" : "SIGTERM");
    fs::remove(log_); // the previous run's lines are not this run's
    const pid_t pid = start(
      {"--config", yaml_.string(), "--frames", "0:8", "--no-snapshot", "--sequential"},
      log_);
    bool first_frame = false;
    for (int waited_ms = 0; !first_frame && waited_ms < 600000; waited_ms += 10) {
      first_frame = fileBytes(log_).find("frame 1/8") != std::string::npos;
      if (!first_frame)
        ::usleep(10000);
    }
    ASSERT_TRUE(first_frame) << fileBytes(log_);
    ASSERT_EQ(::kill(pid, signal), 0);
    EXPECT_EQ(exitCode(pid), 128 + signal);
    const std::string log = fileBytes(log_);
    EXPECT_NE(log.find(std::string(signal == SIGINT ? "SIGINT" : "SIGTERM")
                       + ": stopped on request after frame "),
              std::string::npos)
      << log;
    EXPECT_NE(
      log.find("the previous outputs in " + out_.string() + " are as they were"),
      std::string::npos)
      << log;
    EXPECT_EQ(log.find("frame 8/8"), std::string::npos) << log;
    EXPECT_EQ(contents(out_), old_set);
  }
  fs::remove(log_);
}

TEST(PipelineRunLock, SecondRunIntoTheFolderFailsAtOnceNamingTheHolder)
{
  const fs::path dir =
    fs::temp_directory_path() / ("planar_grid_run_lock_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path folder = dir / "out";
  std::ofstream(dir / "job.yaml") << commitJobConfig(folder);
  std::string what;
  {
    // This process holds the folder as a running pipeline would.
    planar_grid::OutputTransaction running(folder.string());
    const pid_t pid =
      start({"--config", (dir / "job.yaml").string(), "--no-snapshot"}, dir / "log");
    EXPECT_EQ(exitCode(pid), 5);
    what = fileBytes(dir / "log");
    // Refused before the first frame: no progress line, no checkpoint, no output.
    EXPECT_EQ(what.find("frame 1/3"), std::string::npos) << what;
    EXPECT_TRUE(outputs(folder).empty());
  }
  EXPECT_NE(what.find(folder.string()
                      + ": the output folder is in use by another run "
                        "(process "
                      + std::to_string(::getpid()) + " holds"),
            std::string::npos)
    << what;
  fs::remove_all(dir);
}

TEST(PipelineOwnXvfb, FailingRunWithoutDisplayExitsWithItsOwnCodeAndLeavesNoXvfb)
{
  // Without DISPLAY and with snapshots to render, the tool starts its own Xvfb; a run
  // that then fails (a reversed frame range) exits 1 with its own message, and the
  // server goes with it.
  if (::system("command -v Xvfb > /dev/null 2>&1") != 0)
    GTEST_SKIP() << "Xvfb is not installed";
  const fs::path dir =
    fs::temp_directory_path() / ("planar_grid_own_xvfb_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "job.yaml") << commitJobConfig(dir / "out", false);
  // Xvfb servers started with -displayfd (only ours are) and alive now.
  const auto own_servers = [] {
    std::vector<std::string> pids;
    for (const auto& e : fs::directory_iterator("/proc")) {
      const std::string name = e.path().filename().string();
      if (name.find_first_not_of("0123456789") != std::string::npos)
        continue;
      const std::string cmdline = fileBytes(e.path() / "cmdline");
      const std::string stat = fileBytes(e.path() / "stat");
      const bool zombie = stat.find(") Z ") != std::string::npos;
      if (!zombie && cmdline.rfind("Xvfb", 0) == 0
          && cmdline.find("-displayfd") != std::string::npos)
        pids.push_back(e.path().filename().string());
    }
    return pids;
  };
  const auto before = own_servers();
  std::cout.flush();
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::unsetenv("DISPLAY");
    std::freopen((dir / "log").c_str(), "w", stdout);
    ::dup2(STDOUT_FILENO, STDERR_FILENO);
    std::string tool = PLANAR_GRID_PIPELINE_TOOL;
    std::string config_arg = (dir / "job.yaml").string();
    std::vector<char*> argv{tool.data(),
                            const_cast<char*>("--config"),
                            config_arg.data(),
                            const_cast<char*>("--frames"),
                            const_cast<char*>("2:1"),
                            nullptr};
    ::execv(tool.c_str(), argv.data());
    ::_exit(127);
  }
  EXPECT_EQ(exitCode(pid), 2); // a command-line error
  const std::string log = fileBytes(dir / "log");
  EXPECT_NE(log.find("frame range 2:1 is empty"), std::string::npos) << log;
  EXPECT_EQ(log.find("xvfb-run"), std::string::npos) << log;
  // The kernel sends the server SIGTERM when the tool ends; it is gone once it has
  // handled it (bounded wait for that, not a timing measurement).
  std::vector<std::string> left;
  for (int i = 0; i < 100; ++i) {
    left.clear();
    for (const auto& p : own_servers())
      if (std::find(before.begin(), before.end(), p) == before.end())
        left.push_back(p);
    if (left.empty())
      break;
    ::usleep(50000);
  }
  EXPECT_TRUE(left.empty()) << left.size() << " Xvfb left, e.g. pid " << left.front();
  fs::remove_all(dir);
}
