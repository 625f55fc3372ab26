// SPDX-License-Identifier: BSD-3-Clause
// OutputTransaction: the outputs of a run replace the previous ones as one set. A
// failed write, a kill at any step of the commit, or a signal leaves the folder holding
// exactly the old set or the new one, byte for byte.
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/output_transaction.h>

#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using planar_grid::OutputTransaction;

/** Every regular file under \a folder (relative name -> bytes), staging folders and
 * temporaries included, so that a leftover shows up as a difference. */
std::map<std::string, std::string>
contents(const fs::path& folder)
{
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(folder)) {
    // The lock file belongs to the folder, not to an output set.
    if (!e.is_regular_file() || e.path().filename() == OutputTransaction::LOCK)
      continue;
    std::ifstream in(e.path(), std::ios::binary);
    files[fs::relative(e.path(), folder).string()] =
      std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  return files;
}

/** Stages \a files (name -> bytes) through writeTextFileAtomically(). */
void
stage(OutputTransaction& transaction, const std::map<std::string, std::string>& files)
{
  for (const auto& [name, bytes] : files)
    transaction.write(name, [&bytes = bytes](const std::string& path) {
      planar_grid::writeTextFileAtomically(path, bytes);
    });
}

/** The id of a process that has ended (forked, exited and reaped). */
pid_t
deadPid()
{
  const pid_t pid = ::fork();
  if (pid == 0)
    ::_exit(0);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return pid;
}

/** Runs \a body in a child process; returns its wait status. */
int
inChild(const std::function<void()>& body)
{
  const pid_t pid = ::fork();
  if (pid == 0) {
    try {
      body();
    } catch (...) {
      ::_exit(3);
    }
    ::_exit(0);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}

class OutputTransactionTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    dir_ = fs::temp_directory_path()
           / ("planar_grid_output_transaction_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    folder_ = dir_ / "out";
  }
  void TearDown() override { fs::remove_all(dir_); }

  /** Commits \a files as the folder's set; returns the folder's content after it. */
  std::map<std::string, std::string>
  commitSet(const std::map<std::string, std::string>& files)
  {
    OutputTransaction transaction(folder_.string());
    stage(transaction, files);
    transaction.commit();
    return contents(folder_);
  }

  const std::map<std::string, std::string> old_files_{{"map.pgmap", "old map"},
                                                      {"cloud.pcd", "old cloud"},
                                                      {"snapshot.png", "old png"},
                                                      {"sub/c.txt", "old c"}};
  // The new set has no snapshot: the old one goes with the commit.
  const std::map<std::string, std::string> new_files_{{"map.pgmap", "new map, longer"},
                                                      {"cloud.pcd", "new cloud"},
                                                      {"sub/c.txt", "new c"},
                                                      {"report.json", "{}"}};
  fs::path dir_, folder_;
};

TEST_F(OutputTransactionTest, CommitReplacesTheWholeSet)
{
  const auto old_set = commitSet(old_files_);
  EXPECT_EQ(old_set.size(), old_files_.size() + 1); // and the list of the set
  EXPECT_EQ(old_set.at("map.pgmap"), "old map");
  // In the staging order (stage() goes through the std::map, by name).
  EXPECT_EQ(old_set.at(OutputTransaction::MANIFEST),
            "cloud.pcd\nmap.pgmap\nsnapshot.png\nsub/c.txt\n");

  const auto new_set = commitSet(new_files_);
  auto expected = new_files_;
  expected[OutputTransaction::MANIFEST] =
    "cloud.pcd\nmap.pgmap\nreport.json\nsub/c.txt\n";
  EXPECT_EQ(new_set, expected); // old snapshot removed, nothing else left over
}

TEST_F(OutputTransactionTest, NothingChangesBeforeTheCommitAndWithoutIt)
{
  const auto old_set = commitSet(old_files_);
  {
    OutputTransaction transaction(folder_.string());
    stage(transaction, new_files_);
    // Staged, not committed: the outputs are unchanged (the staging folder aside).
    auto visible = contents(folder_);
    for (auto it = visible.begin(); it != visible.end();)
      it = it->first.rfind(OutputTransaction::STAGING_PREFIX, 0) == 0
             ? visible.erase(it)
             : std::next(it);
    EXPECT_EQ(visible, old_set);
  }
  EXPECT_EQ(contents(folder_), old_set); // the abandoned staging folder is gone
}

TEST_F(OutputTransactionTest, FailedWriteNamesTheFinalFileAndKeepsTheOldSet)
{
  const auto old_set = commitSet(old_files_);
  {
    OutputTransaction transaction(folder_.string());
    stage(transaction, {{"map.pgmap", "new map"}});
    try {
      transaction.write("cloud.pcd", [](const std::string& path) {
        throw planar_grid::IOError(path + ": cannot write: No space left on device");
      });
      ADD_FAILURE() << "no exception";
    } catch (const planar_grid::IOError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find((folder_ / "cloud.pcd").string()
                          + ": cannot write: No space left on device"),
                std::string::npos)
        << what;
      EXPECT_EQ(what.find(OutputTransaction::STAGING_PREFIX), std::string::npos)
        << what;
      EXPECT_NE(what.find("previous set is kept"), std::string::npos) << what;
    }
  }
  EXPECT_EQ(contents(folder_), old_set);
}

TEST_F(OutputTransactionTest, FileSizeLimitIsAnErrorNamingTheFileAndTheCause)
{
  const auto old_set = commitSet(old_files_);
  // A child with a 1000-byte file size limit (RLIMIT_FSIZE, what `ulimit -f` sets)
  // stages a 5000-byte file: the write fails with EFBIG like on a full disk.
  const fs::path message = dir_ / "message.txt";
  const int status = inChild([&] {
    ::signal(SIGXFSZ, SIG_IGN); // else the kernel stops the process at the limit
    const rlimit limit{1000, 1000};
    ::setrlimit(RLIMIT_FSIZE, &limit);
    OutputTransaction transaction(folder_.string());
    try {
      stage(transaction, {{"map.pgmap", std::string(5000, 'x')}});
    } catch (const planar_grid::IOError& e) {
      std::ofstream(message) << e.what();
      ::_exit(1);
    }
  });
  ASSERT_TRUE(WIFEXITED(status)) << status;
  EXPECT_EQ(WEXITSTATUS(status), 1);
  std::ifstream in(message);
  const std::string what((std::istreambuf_iterator<char>(in)),
                         std::istreambuf_iterator<char>());
  EXPECT_NE(
    what.find((folder_ / "map.pgmap").string() + ": cannot write: File too large"),
    std::string::npos)
    << what;
  EXPECT_NE(what.find("ulimit -f: 1000 bytes"), std::string::npos) << what;
  EXPECT_EQ(contents(folder_), old_set);
}

TEST_F(OutputTransactionTest, KilledAtEveryStepLeavesTheOldOrTheNewSet)
{
  // The steps of a commit of new_files_ over old_files_: synced, journal, one put per
  // file and the list, one remove, done. Kill the writer (SIGKILL) before the commit
  // and after each step; the next transaction on the folder finishes or drops it.
  auto new_set = new_files_;
  new_set[OutputTransaction::MANIFEST] =
    "cloud.pcd\nmap.pgmap\nreport.json\nsub/c.txt\n";
  const int steps = 2 + static_cast<int>(new_files_.size()) + 1 + 1 + 1;
  for (int kill_at = -1; kill_at < steps; ++kill_at) {
    SCOPED_TRACE("killed after step " + std::to_string(kill_at));
    fs::remove_all(folder_);
    const auto old_set = commitSet(old_files_);
    const int status = inChild([&] {
      OutputTransaction transaction(folder_.string());
      stage(transaction, new_files_);
      if (kill_at < 0)
        ::raise(SIGKILL);
      int done = 0;
      transaction.setStepCallback([&](const std::string&) {
        if (done++ == kill_at)
          ::raise(SIGKILL);
      });
      transaction.commit();
    });
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << status;
    const bool journal = fs::exists(folder_ / OutputTransaction::JOURNAL);
    // Before the journal (kill_at < 1), the old set is untouched.
    EXPECT_EQ(journal, kill_at >= 1 && kill_at < steps - 1);
    {
      OutputTransaction next(folder_.string());
    } // recovers, then abandons
    EXPECT_EQ(contents(folder_), kill_at < 1 ? old_set : new_set);
  }
}

TEST_F(OutputTransactionTest, InterruptDuringTheCommitWaitsForTheWholeSet)
{
  const auto old_set = commitSet(old_files_);
  const int status = inChild([&] {
    OutputTransaction transaction(folder_.string());
    stage(transaction, new_files_);
    transaction.setStepCallback([](const std::string& step) {
      if (step == "put map.pgmap")
        ::raise(SIGINT); // Ctrl-C between two renames
    });
    transaction.commit();
    ::_exit(0); // not reached: the held SIGINT ends the process after the commit
  });
  ASSERT_TRUE(WIFSIGNALED(status)) << status;
  EXPECT_EQ(WTERMSIG(status), SIGINT);
  auto expected = new_files_;
  expected[OutputTransaction::MANIFEST] =
    "cloud.pcd\nmap.pgmap\nreport.json\nsub/c.txt\n";
  EXPECT_EQ(contents(folder_), expected); // complete, without a journal
}

TEST_F(OutputTransactionTest, StaleStagingFoldersAndTemporariesAreRemoved)
{
  const auto old_set = commitSet(old_files_);
  const std::string dead = std::to_string(deadPid());
  const std::string alive = std::to_string(::getppid());
  fs::create_directories(folder_ / (OutputTransaction::STAGING_PREFIX + dead) / "sub");
  std::ofstream(folder_ / (OutputTransaction::STAGING_PREFIX + dead) / "sub" / "x")
    << "half";
  std::ofstream(folder_ / (".map.pgmap.tmp." + dead)) << "half";
  std::ofstream(folder_ / (std::string(OutputTransaction::JOURNAL) + ".tmp." + dead))
    << "half";
  std::ofstream(folder_ / (".cloud.pcd.tmp." + alive)) << "a live writer's";
  std::ofstream(folder_ / "notes.tmp.1") << "the user's"; // not one of ours
  {
    OutputTransaction transaction(folder_.string());
  }
  auto expected = old_set;
  expected[".cloud.pcd.tmp." + alive] = "a live writer's";
  expected["notes.tmp.1"] = "the user's";
  EXPECT_EQ(contents(folder_), expected);
}

TEST_F(OutputTransactionTest, CorruptJournalIsAnErrorNamingIt)
{
  commitSet(old_files_);
  std::ofstream(folder_ / OutputTransaction::JOURNAL)
    << "planar_grid output commit 1\n";
  try {
    OutputTransaction transaction(folder_.string());
    ADD_FAILURE() << "no exception";
  } catch (const planar_grid::IOError& e) {
    EXPECT_NE(std::string(e.what()).find((folder_ / OutputTransaction::JOURNAL).string()
                                         + ": corrupt commit journal"),
              std::string::npos)
      << e.what();
  }
}

TEST_F(OutputTransactionTest, BadNamesAndUnusableFoldersAreErrors)
{
  {
    OutputTransaction transaction(folder_.string());
    for (const std::string name :
         {"../x.pcd", "/tmp/x.pcd", "", ".planar_grid_outputs", "a/../../x"})
      EXPECT_THROW(transaction.stagedPath(name), planar_grid::IOError) << name;
  }
  std::ofstream(dir_ / "a_file") << "x";
  try {
    OutputTransaction transaction((dir_ / "a_file").string());
    ADD_FAILURE() << "no exception";
  } catch (const planar_grid::IOError& e) {
    EXPECT_NE(std::string(e.what()).find("a_file: the output folder is a file"),
              std::string::npos)
      << e.what();
  }
  // A folder this process may not write into: as root, a child that drops to the
  // unprivileged user "nobody" (65534); otherwise a folder without write permission.
  const fs::path locked = dir_ / "locked";
  fs::create_directories(locked);
  fs::permissions(dir_, fs::perms::owner_all | fs::perms::group_read
                          | fs::perms::group_exec | fs::perms::others_read
                          | fs::perms::others_exec);
  fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec
                            | fs::perms::group_read | fs::perms::group_exec
                            | fs::perms::others_read | fs::perms::others_exec);
  const fs::path message =
    fs::temp_directory_path() / ("planar_grid_locked_" + std::to_string(::getpid()));
  const int status = inChild([&] {
    if (::geteuid() == 0 && (::setgid(65534) != 0 || ::setuid(65534) != 0))
      ::_exit(2);
    try {
      OutputTransaction transaction(locked.string());
    } catch (const planar_grid::IOError& e) {
      std::ofstream(message) << e.what();
      ::_exit(1);
    }
  });
  fs::permissions(locked, fs::perms::owner_all);
  ASSERT_TRUE(WIFEXITED(status)) << status;
  ASSERT_EQ(WEXITSTATUS(status), 1);
  std::ifstream in(message);
  const std::string what((std::istreambuf_iterator<char>(in)),
                         std::istreambuf_iterator<char>());
  fs::remove(message);
  EXPECT_NE(what.find(locked.string() + ": cannot write into the output folder"),
            std::string::npos)
    << what;
  EXPECT_NE(what.find("Permission denied"), std::string::npos) << what;
}

} // namespace

TEST_F(OutputTransactionTest, SecondRunIntoTheFolderFailsNamingTheHolder)
{
  const std::string own_pid = std::to_string(static_cast<long>(::getpid()));
  {
    OutputTransaction first(folder_.string());
    // flock(2) locks belong to the open file: a second transaction fails even in the
    // same process.
    try {
      OutputTransaction second(folder_.string());
      ADD_FAILURE() << "no exception";
    } catch (const planar_grid::IOError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(folder_.string()
                          + ": the output folder is in use by another "
                            "run (process "
                          + own_pid + " holds"),
                std::string::npos)
        << what;
    }
    // The failed transaction touched nothing of the holder's: its staging folder is
    // still there.
    EXPECT_TRUE(fs::is_directory(first.getStagingFolder()));
  }
  // Released with the transaction: the next one opens the folder.
  EXPECT_NO_THROW(OutputTransaction third(folder_.string()));
}

TEST_F(OutputTransactionTest, LockFileIsNotFollowedThroughALink)
{
  // A link in the lock file's place would have the run truncate its target and write
  // its process id into it: the run refuses, naming the link, and the target keeps
  // its bytes.
  fs::create_directories(folder_);
  const fs::path precious = dir_ / "precious.txt";
  {
    std::ofstream(precious) << "keep me";
  }
  fs::create_symlink(precious, folder_ / OutputTransaction::LOCK);
  try {
    OutputTransaction transaction(folder_.string());
    ADD_FAILURE() << "no exception";
  } catch (const planar_grid::IOError& e) {
    EXPECT_NE(std::string(e.what()).find("is a symbolic link"), std::string::npos)
      << e.what();
  }
  std::ifstream in(precious);
  const std::string text((std::istreambuf_iterator<char>(in)),
                         std::istreambuf_iterator<char>());
  EXPECT_EQ(text, "keep me");
}

TEST_F(OutputTransactionTest, NamesThroughALinkedFolderTouchNothingOutside)
{
  // The old set has sub/c.txt; sub is then replaced by a link to another folder that
  // holds a file of the same name. The next set without sub/c.txt must not remove the
  // linked file, and a set with sub/c.txt must not write through the link.
  commitSet(old_files_);
  const fs::path elsewhere = dir_ / "elsewhere";
  fs::create_directories(elsewhere);
  {
    std::ofstream(elsewhere / "c.txt") << "not ours";
  }
  fs::remove_all(folder_ / "sub");
  fs::create_symlink(elsewhere, folder_ / "sub");
  auto without_sub = new_files_;
  without_sub.erase("sub/c.txt");
  commitSet(without_sub);
  ASSERT_TRUE(fs::exists(elsewhere / "c.txt"));
  try {
    commitSet(new_files_);
    ADD_FAILURE() << "no exception";
  } catch (const planar_grid::IOError& e) {
    EXPECT_NE(std::string(e.what()).find("is a symbolic link"), std::string::npos)
      << e.what();
  }
  std::ifstream in(elsewhere / "c.txt");
  const std::string text((std::istreambuf_iterator<char>(in)),
                         std::istreambuf_iterator<char>());
  EXPECT_EQ(text, "not ours");
}

TEST_F(OutputTransactionTest, LockOfAKilledRunIsReleased)
{
  // A child takes the folder and waits; while it lives the folder is refused, naming
  // its process id; once it is killed (SIGKILL: no destructor runs) the kernel has
  // released the lock.
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(ready[0]);
    OutputTransaction holder(folder_.string());
    const char byte = 1;
    if (::write(ready[1], &byte, 1) != 1)
      ::_exit(3);
    ::pause();
    ::_exit(0);
  }
  ::close(ready[1]);
  char byte = 0;
  ASSERT_EQ(::read(ready[0], &byte, 1), 1);
  ::close(ready[0]);
  try {
    OutputTransaction second(folder_.string());
    ADD_FAILURE() << "no exception";
  } catch (const planar_grid::IOError& e) {
    EXPECT_NE(
      std::string(e.what()).find("(process " + std::to_string(child) + " holds"),
      std::string::npos)
      << e.what();
  }
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status));
  OutputTransaction after(folder_.string());
  // The killed run's staging folder was removed by this one.
  EXPECT_FALSE(
    fs::exists(folder_ / (OutputTransaction::STAGING_PREFIX + std::to_string(child))));
}

TEST_F(OutputTransactionTest, PCDWriterFailureNamesTheFileAndTheCause)
{
  // pcl::PCDWriter's own error names neither ("[pcl::PCDWriter::writeBinaryCompressed]
  // Error during open!"): the write names the output and the errno's cause.
  pcl::PointCloud<pcl::PointXYZ> cloud;
  cloud.push_back(pcl::PointXYZ(1.0f, 2.0f, 3.0f));
  const auto write_pcd = [&cloud](const std::string& path) {
    planar_grid::writeFileAtomically(path, [&cloud](const std::string& tmp) {
      pcl::PCDWriter writer;
      return writer.writeBinaryCompressed(tmp, cloud) == 0;
    });
  };
  // A folder this process may not write into (as root: a child dropped to "nobody").
  const fs::path locked = dir_ / "read_only";
  fs::create_directories(locked);
  fs::permissions(dir_, fs::perms::owner_all | fs::perms::group_read
                          | fs::perms::group_exec | fs::perms::others_read
                          | fs::perms::others_exec);
  fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec
                            | fs::perms::group_read | fs::perms::group_exec
                            | fs::perms::others_read | fs::perms::others_exec);
  const fs::path message = fs::temp_directory_path()
                           / ("planar_grid_pcd_denied_" + std::to_string(::getpid()));
  const int status = inChild([&] {
    if (::geteuid() == 0 && (::setgid(65534) != 0 || ::setuid(65534) != 0))
      ::_exit(2);
    try {
      write_pcd((locked / "cloud.pcd").string());
    } catch (const planar_grid::IOError& e) {
      std::ofstream(message) << e.what();
      ::_exit(1);
    }
  });
  fs::permissions(locked, fs::perms::owner_all);
  ASSERT_TRUE(WIFEXITED(status)) << status;
  ASSERT_EQ(WEXITSTATUS(status), 1);
  std::ifstream in(message);
  const std::string what((std::istreambuf_iterator<char>(in)),
                         std::istreambuf_iterator<char>());
  fs::remove(message);
  EXPECT_NE(
    what.find((locked / "cloud.pcd").string() + ": cannot write: Permission denied"),
    std::string::npos)
    << what;
  EXPECT_NE(what.find("Error during open!"), std::string::npos) << what;
  EXPECT_FALSE(fs::exists(locked / "cloud.pcd"));
}
