// SPDX-License-Identifier: BSD-3-Clause
// No lost work: planar_grid_pipeline killed (SIGKILL) while it writes its
// checkpoint leaves the previous checkpoint intact, --resume continues from it, and the
// map at the end is byte-identical to the map of a run never killed.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/inotify.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "karlsruhe_job.h"

namespace fs = std::filesystem;

namespace {

/** Karlsruhe frames 10-15 through the paper pipeline with the map, a checkpoint after
 * every frame, no snapshots. */
std::string
config(const fs::path& output)
{
  return planar_grid::test::karlsruheJob(
    6, output,
    "  snapshot: \"\"\n  planes_snapshot: \"\"\n  cuboids_snapshot: \"\"\n"
    "  map_snapshot: \"\"\n  map_octomap: \"\"\n  map_mesh: \"\"\n"
    "  checkpoint: checkpoint.pgck\n  checkpoint_every_n_frames: 1\n");
}

/** Starts planar_grid_pipeline with \a args (output to /dev/null); returns its pid. */
pid_t
start(const std::vector<std::string>& args)
{
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::vector<char*> argv;
    static std::string tool = PLANAR_GRID_PIPELINE_TOOL;
    argv.push_back(tool.data());
    std::vector<std::string> copies = args;
    for (auto& a : copies)
      argv.push_back(a.data());
    argv.push_back(nullptr);
    std::freopen("/dev/null", "w", stdout);
    std::freopen("/dev/null", "w", stderr);
    ::execv(tool.c_str(), argv.data());
    ::_exit(127);
  }
  return pid;
}

int
waitExit(pid_t pid)
{
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}

std::string
bytesOf(const fs::path& file)
{
  std::ifstream in(file.string(), std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in),
                     std::istreambuf_iterator<char>());
}

/** The temporary files of an interrupted checkpoint write in \a folder. */
std::vector<fs::path>
temporaries(const fs::path& folder)
{
  std::vector<fs::path> found;
  for (const auto& e : fs::directory_iterator(folder))
    if (e.path().filename().string().rfind(".checkpoint.pgck.tmp.", 0) == 0)
      found.push_back(e.path());
  return found;
}

class KillDuringCheckpointTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    dir_ =
      fs::temp_directory_path() / ("planar_grid_kill_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "straight");
    fs::create_directories(dir_ / "killed");
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(KillDuringCheckpointTest, KilledWhileWritingThenResumedGivesTheSameMap)
{
  const fs::path straight_yaml = dir_ / "straight.yaml";
  const fs::path killed_yaml = dir_ / "killed.yaml";
  std::ofstream(straight_yaml) << config(dir_ / "straight");
  std::ofstream(killed_yaml) << config(dir_ / "killed");

  // The reference: one run, never interrupted.
  const int straight = waitExit(start({"--config", straight_yaml.string()}));
  ASSERT_TRUE(WIFEXITED(straight) && WEXITSTATUS(straight) == 0);
  const std::string reference = bytesOf(dir_ / "straight" / "map.pgmap");
  ASSERT_GT(reference.size(), 100000u);

  // Kill the run the moment it creates the temporary file of a checkpoint (inotify),
  // i.e. while the checkpoint is being written, then resume; repeat until the run
  // finishes. Each resume reads the previous checkpoint, which must be intact.
  const fs::path out = dir_ / "killed";
  int kills = 0, mid_write = 0, finished = 0;
  constexpr int MAX_KILLS = 4;
  for (int attempt = 0; attempt <= MAX_KILLS && !finished; ++attempt) {
    const int watch_fd = ::inotify_init1(IN_NONBLOCK);
    ASSERT_GE(watch_fd, 0);
    ASSERT_GE(::inotify_add_watch(watch_fd, out.c_str(), IN_CREATE), 0);
    std::vector<std::string> args{"--config", killed_yaml.string()};
    if (fs::exists(out / "checkpoint.pgck"))
      args.push_back("--resume");
    const pid_t pid = start(args);
    bool killed = false;
    // Let the first attempts run past their first checkpoint, so that later kills
    // interrupt the replacement of an existing checkpoint.
    const int skip = attempt % 2;
    int seen = 0;
    while (!killed) {
      int status = 0;
      if (::waitpid(pid, &status, WNOHANG) == pid) {
        ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
          << "the resumed run failed (status " << status << ")";
        finished = 1;
        break;
      }
      pollfd p{watch_fd, POLLIN, 0};
      if (::poll(&p, 1, 20) <= 0)
        continue;
      alignas(inotify_event) char buffer[4096];
      const ssize_t n = ::read(watch_fd, buffer, sizeof(buffer));
      for (ssize_t i = 0; i < n;) {
        const auto* event = reinterpret_cast<const inotify_event*>(buffer + i);
        const std::string name = event->len ? event->name : "";
        if (kills < MAX_KILLS && name.rfind(".checkpoint.pgck.tmp.", 0) == 0
            && seen++ >= skip) {
          ::kill(pid, SIGKILL);
          waitExit(pid);
          killed = true;
          ++kills;
          break;
        }
        i += static_cast<ssize_t>(sizeof(inotify_event) + event->len);
      }
    }
    ::close(watch_fd);
    if (killed && !temporaries(out).empty())
      ++mid_write; // the write did not reach its rename
  }
  EXPECT_TRUE(finished) << "the run never finished after " << kills << " kills";
  EXPECT_GE(kills, 2);
  EXPECT_GE(mid_write, 1) << "no kill landed inside a checkpoint write";
  // The resumed run removed the temporaries the killed ones left.
  EXPECT_TRUE(temporaries(out).empty());
  EXPECT_TRUE(bytesOf(out / "map.pgmap") == reference)
    << "the map after " << kills << " kills (" << mid_write
    << " during a checkpoint write) differs from the uninterrupted run's";
  std::cout << "[ kill ] " << kills << " kills, " << mid_write
            << " inside a checkpoint write; map identical to the uninterrupted run\n";
}

} // namespace
