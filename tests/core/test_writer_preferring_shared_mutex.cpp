// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/writer_preferring_shared_mutex.h>

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <shared_mutex>
#include <string>
#include <thread>
#include <vector>

namespace {

/** Waits (up to 30 s) until a writer waits on \a mutex held shared by the caller: new
 * readers are then refused. */
bool
waitForWaitingWriter(planar_grid::WriterPreferringSharedMutex& mutex)
{
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (std::chrono::steady_clock::now() < deadline) {
    if (!mutex.try_lock_shared())
      return true;
    mutex.unlock_shared();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return false;
}

} // namespace

TEST(WriterPreferringSharedMutex, ReadersShareAndAWriterExcludesEveryone)
{
  planar_grid::WriterPreferringSharedMutex mutex;
  ASSERT_TRUE(mutex.try_lock_shared());
  ASSERT_TRUE(mutex.try_lock_shared()); // two readers at once
  EXPECT_FALSE(mutex.try_lock());
  mutex.unlock_shared();
  EXPECT_FALSE(mutex.try_lock());
  mutex.unlock_shared();
  ASSERT_TRUE(mutex.try_lock());
  EXPECT_FALSE(mutex.try_lock_shared());
  EXPECT_FALSE(mutex.try_lock());
  mutex.unlock();
  // The standard lock types use it.
  {
    const std::shared_lock<planar_grid::WriterPreferringSharedMutex> a(mutex);
    const std::shared_lock<planar_grid::WriterPreferringSharedMutex> b(mutex);
    EXPECT_FALSE(mutex.try_lock());
  }
  const std::unique_lock<planar_grid::WriterPreferringSharedMutex> w(mutex);
  EXPECT_FALSE(mutex.try_lock_shared());
}

TEST(WriterPreferringSharedMutex, AWaitingWriterGoesBeforeTheReadersThatCameAfterIt)
{
  planar_grid::WriterPreferringSharedMutex mutex;
  std::mutex order_mutex;
  std::vector<std::string> order;
  const auto record = [&](const std::string& who) {
    const std::lock_guard<std::mutex> guard(order_mutex);
    order.push_back(who);
  };
  mutex.lock_shared(); // the reader already inside
  std::thread writer([&] {
    mutex.lock();
    record("writer");
    mutex.unlock();
  });
  ASSERT_TRUE(waitForWaitingWriter(mutex));
  // A reader arriving now waits behind the writer, although only readers hold the
  // mutex.
  std::atomic<bool> reader_started{false};
  std::thread late_reader([&] {
    reader_started = true;
    mutex.lock_shared();
    record("late reader");
    mutex.unlock_shared();
  });
  while (!reader_started)
    std::this_thread::yield();
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  {
    const std::lock_guard<std::mutex> guard(order_mutex);
    EXPECT_TRUE(order.empty())
      << order.front() << " got in before the first reader left";
  }
  mutex.unlock_shared(); // the writer, then the late reader
  writer.join();
  late_reader.join();
  EXPECT_EQ(order, (std::vector<std::string>{"writer", "late reader"}));
}

TEST(WriterPreferringSharedMutex, ReadersInALoopDoNotStarveAWriter)
{
  // Two readers whose holds overlap all the time: with a reader-preferring lock the
  // mutex would never be free. The writer gets in within a few holds.
  planar_grid::WriterPreferringSharedMutex mutex;
  std::atomic<bool> stop{false};
  std::atomic<long> reads{0};
  const auto read_loop = [&] {
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (!stop && std::chrono::steady_clock::now() < give_up) {
      const std::shared_lock<planar_grid::WriterPreferringSharedMutex> hold(mutex);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
      ++reads;
    }
  };
  std::thread a(read_loop), b(read_loop);
  while (reads < 10)
    std::this_thread::yield();
  for (int i = 0; i < 5; ++i) {
    const long before = reads.load();
    mutex.lock();
    const long during = reads.load();
    mutex.unlock();
    // Only the holds under way when the writer came (and one a reader may have begun
    // just before) finished before it got in.
    EXPECT_LE(during - before, 4) << "write " << i;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  stop = true;
  a.join();
  b.join();
}
