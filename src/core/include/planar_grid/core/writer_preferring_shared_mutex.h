// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <condition_variable>
#include <cstddef>
#include <mutex>

namespace planar_grid {

/** \brief A shared mutex (the standard SharedMutex requirements: lock(), unlock(),
 * lock_shared(), unlock_shared() and their try_ forms, for std::unique_lock and
 * std::shared_lock) that prefers writers: once a writer waits, new readers wait behind
 * it, so a writer waits at most for the readers already inside, however many threads
 * read in a loop. std::shared_mutex leaves the order to the platform (glibc lets new
 * readers pass a waiting writer, which can starve it).
 *
 * As with any writer-preferring lock, a thread must not take a shared lock while it
 * already holds one: with a writer waiting between the two, the second would wait for
 * the writer and the writer for the first. \ingroup core */
class WriterPreferringSharedMutex {
public:
  WriterPreferringSharedMutex() = default;
  WriterPreferringSharedMutex(const WriterPreferringSharedMutex&) = delete;
  WriterPreferringSharedMutex& operator=(const WriterPreferringSharedMutex&) = delete;

  /** \brief Waits until no reader and no writer holds the mutex, then holds it
   * exclusively; readers arriving meanwhile wait behind. */
  void lock()
  {
    std::unique_lock<std::mutex> guard(state_mutex_);
    ++waiting_writers_;
    writer_cv_.wait(guard, [this] { return !writer_ && readers_ == 0; });
    --waiting_writers_;
    writer_ = true;
  }

  /** \brief Holds the mutex exclusively when it is free; never waits.
   * \return whether it is now held */
  bool try_lock()
  {
    const std::lock_guard<std::mutex> guard(state_mutex_);
    if (writer_ || readers_ > 0)
      return false;
    writer_ = true;
    return true;
  }

  /** \brief Releases the exclusive hold. */
  void unlock()
  {
    {
      const std::lock_guard<std::mutex> guard(state_mutex_);
      writer_ = false;
    }
    writer_cv_.notify_one();
    reader_cv_.notify_all();
  }

  /** \brief Waits until no writer holds or waits for the mutex, then holds it shared.
   */
  void lock_shared()
  {
    std::unique_lock<std::mutex> guard(state_mutex_);
    reader_cv_.wait(guard, [this] { return !writer_ && waiting_writers_ == 0; });
    ++readers_;
  }

  /** \brief Holds the mutex shared when no writer holds or waits for it; never waits.
   * \return whether it is now held */
  bool try_lock_shared()
  {
    const std::lock_guard<std::mutex> guard(state_mutex_);
    if (writer_ || waiting_writers_ > 0)
      return false;
    ++readers_;
    return true;
  }

  /** \brief Releases one shared hold; the last reader lets a waiting writer in. */
  void unlock_shared()
  {
    bool last = false;
    {
      const std::lock_guard<std::mutex> guard(state_mutex_);
      last = --readers_ == 0;
    }
    if (last)
      writer_cv_.notify_one();
  }

private:
  std::mutex state_mutex_;
  std::condition_variable writer_cv_;
  std::condition_variable reader_cv_;
  std::size_t readers_{0};
  std::size_t waiting_writers_{0};
  bool writer_{false};
};

} // namespace planar_grid
