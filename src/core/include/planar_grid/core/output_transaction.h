// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief Replaces the outputs of a run in a folder as one set: a reader of the folder
 * finds the previous set or the new one, never a mix, whatever happens while they are
 * written (a full disk, a read-only folder, SIGKILL, SIGINT).
 *
 * Every output is written into a staging folder inside the output folder (the same
 * file system, so that moving a file into place is a rename(2)). commit() then syncs
 * the staged files and writes a journal, ".planar_grid_commit", listing the files to
 * move in and the files of the previous set to remove; the journal is renamed into
 * place (the commit point), after which the files are renamed into the folder, the
 * journal removed and the staging folder deleted. A process killed before the journal
 * exists leaves the previous set untouched; killed after it, the next
 * OutputTransaction on the folder (or recover()) finishes the renames, as a database
 * replays its redo log. SIGINT, SIGTERM and SIGHUP that arrive during the renames are
 * held until they are done. The folder keeps the list of the current set in
 * ".planar_grid_outputs", so that a file of the previous set that the new one does not
 * have (a snapshot not rendered this time) is removed with the commit.
 *
 * Opening a transaction locks the folder for the transaction's life (flock(2) on
 * ".planar_grid_lock", which the kernel releases when the process ends, however it
 * ends): a second run into the same folder fails at once, naming the folder and the
 * holder's process id, instead of the two overwriting each other's outputs. It also
 * removes what killed runs left behind: staging folders and temporary files
 * (".<name>.tmp.<pid>") of processes that no longer run.
 *
 * Not thread-safe; one transaction per folder and process at a time.
 * \ingroup core */
class OutputTransaction {
public:
  /** \brief The journal of a commit in progress, in the output folder. */
  static constexpr const char* JOURNAL = ".planar_grid_commit";
  /** \brief The list of the current output set, one name per line, in the folder. */
  static constexpr const char* MANIFEST = ".planar_grid_outputs";
  /** \brief The staging folders' names: this prefix and the writer's process id. */
  static constexpr const char* STAGING_PREFIX = ".planar_grid_staging.";
  /** \brief The lock file in the output folder: the run holding an exclusive
   * flock(2) on it owns the folder; it holds the owner's process id. */
  static constexpr const char* LOCK = ".planar_grid_lock";

  /** \brief Whether \a name may name an output of the set: a relative path of a file
   * that stays inside the folder (not empty, not absolute, not starting with '..' or
   * '.', not ending in a folder separator, no newline, not one of the transaction's
   * own ".planar_grid_" names). The pipeline's configuration checks its output names
   * with it when it is read, before any frame runs. */
  static bool isOutputName(const std::string& name);

  /** \brief Opens \a folder for a new output set: creates it if needed, finishes a
   * commit a killed process left (recover()), removes stale staging folders and
   * temporaries, and creates this process's staging folder.
   * \param[in] folder the output folder
   * \throws planar_grid::IOError naming the folder and the cause when it cannot be
   * created or written (a file of that name, "Permission denied", "Read-only file
   * system"), when another process holds its lock ("in use by another run (process
   * N ...)"), or when a journal is unreadable */
  explicit OutputTransaction(std::string folder);

  /** \brief Without commit(): removes the staging folder; the previous set stays. */
  ~OutputTransaction();

  OutputTransaction(const OutputTransaction&) = delete;
  OutputTransaction& operator=(const OutputTransaction&) = delete;

  /** \brief Where to write the output \a name (a relative path inside the folder) so
   * that commit() moves it into place; records \a name as part of the set.
   * \throws planar_grid::IOError for an absolute name, one with "..", or one of the
   * reserved names above */
  std::string stagedPath(const std::string& name);

  /** \brief Where \a name is after commit(): folder / name. */
  [[nodiscard]] std::string finalPath(const std::string& name) const;

  /** \brief Writes the output \a name with \a write, given its staged path. An
   * exception of \a write whose message names the staged path is rethrown as
   * planar_grid::IOError naming the final file instead, with the note that the
   * previous outputs are unchanged.
   * \param[in] name the output's name inside the folder
   * \param[in] write writes the whole file at the path it is given (e.g. with
   * writeFileAtomically()) and throws on failure
   * \return the final path */
  std::string write(const std::string& name,
                    const std::function<void(const std::string&)>& write);

  /** \brief Moves every staged output into the folder as one step (see the class).
   * \throws planar_grid::IOError naming the file when a staged output is missing or
   * cannot be synced, when an output's name is a folder in the output folder (a file
   * cannot replace it), or the journal cannot be written: the previous set is then
   * unchanged. An error during the renames themselves leaves the journal, and the next
   * transaction on the folder completes them; a folder made in an output's place
   * after the journal is found before the first rename, so the renames do not stop
   * part way on it. */
  void commit();

  /** \brief Finishes a commit that a killed process left in \a folder (its journal):
   * renames the rest of its files into place and removes the ones it drops. Nothing
   * happens when there is no journal.
   * \throws planar_grid::IOError naming the journal when it is unreadable or names a
   * file outside the folder, naming the file when an output's place is a folder
   * (before any rename; remove the folder and recover again), or a rename fails */
  static void recover(const std::string& folder);

  /** \brief Called with a step's name after each step of commit() ("synced",
   * "journal", "put <name>", "remove <name>", "done"); tests use it to stop a process
   * at every step. */
  void setStepCallback(std::function<void(const std::string&)> callback)
  {
    step_callback_ = std::move(callback);
  }

  /** \brief The output folder. */
  [[nodiscard]] const std::string& getFolder() const { return folder_; }

  /** \brief This transaction's staging folder (inside the output folder). */
  [[nodiscard]] const std::string& getStagingFolder() const { return staging_; }

  /** \brief The names staged so far, in order. */
  [[nodiscard]] const std::vector<std::string>& getNames() const { return names_; }

private:
  /** \brief Reports \a step to the step callback, if any. */
  void step(const std::string& name) const;
  /** \brief Takes the folder's lock (LOCK) or throws naming the holder. */
  void lock();

  /** \brief The output folder. */
  std::string folder_;
  /** \brief The staging folder. */
  std::string staging_;
  /** \brief The staged names, in the order they were staged. */
  std::vector<std::string> names_;
  /** \brief Whether commit() has finished. */
  bool committed_{false};
  /** \brief Whether commit() has written its journal (the commit point). */
  bool journal_written_{false};
  /** \brief The open lock file (flock held), or -1. */
  int lock_fd_{-1};
  /** \brief Called after each step of commit(). */
  std::function<void(const std::string&)> step_callback_;
};

} // namespace planar_grid
