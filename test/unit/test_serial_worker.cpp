// The nodelet's estimator thread (serial_worker.h): tasks run one at a time in push order, a push
// never waits for a running task, the backlog is bounded and counted, and stop() drops what
// waits.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <thread>
#include <vector>

#include "mvis/common/serial_worker.h"

namespace mvis {
namespace {

TEST(SerialWorker, RunsTasksInOrderWithoutBlockingThePusher) {
  SerialWorker worker(100);
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::vector<int> order;
  std::promise<void> started;
  ASSERT_TRUE(worker.push([&started, released] {  // a long "solve"
    started.set_value();
    released.wait();
  }));
  started.get_future().wait();
  const auto start = std::chrono::steady_clock::now();
  for (int k = 0; k < 50; ++k) ASSERT_TRUE(worker.push([&order, k] { order.push_back(k); }));
  const double push_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(push_s, 0.5);  // 50 pushes behind a task that never ends until released
  const SerialWorker::Backlog waiting = worker.backlog();
  EXPECT_EQ(waiting.tasks, 50u);
  EXPECT_GE(waiting.oldest_s, 0.0);
  release.set_value();
  ASSERT_TRUE(worker.runAndWait([] {}, 10.0));
  ASSERT_EQ(order.size(), 50u);
  for (int k = 0; k < 50; ++k) EXPECT_EQ(order[k], k);
  EXPECT_EQ(worker.backlog().tasks, 0u);
}

TEST(SerialWorker, RefusesBeyondItsBoundAndDropsOnStop) {
  SerialWorker worker(3);
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::atomic<int> ran{0};
  std::promise<void> started;
  ASSERT_TRUE(worker.push([&started, released] {
    started.set_value();
    released.wait();
  }));
  started.get_future().wait();  // the first task runs: it no longer counts as waiting
  for (int k = 0; k < 3; ++k) EXPECT_TRUE(worker.push([&ran] { ++ran; }));
  EXPECT_FALSE(worker.push([&ran] { ++ran; }));
  EXPECT_FALSE(worker.runAndWait([&ran] { ++ran; }, 0.01));
  EXPECT_EQ(worker.backlog().refused, 2u);
  release.set_value();
  for (int k = 0; k < 1000 && ran.load() < 3; ++k) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(ran.load(), 3);
  EXPECT_TRUE(worker.runAndWait([] {}, 10.0));
  // Stopped while a task runs: it finishes, the waiting ones are dropped, pushes are refused.
  std::promise<void> release2;
  std::shared_future<void> released2 = release2.get_future().share();
  std::promise<void> started2;
  ASSERT_TRUE(worker.push([&started2, released2] {
    started2.set_value();
    released2.wait();
  }));
  started2.get_future().wait();
  ASSERT_TRUE(worker.push([&ran] { ++ran; }));
  std::thread stopper([&] { release2.set_value(); });
  EXPECT_EQ(worker.stop(), 1u);
  stopper.join();
  EXPECT_EQ(ran.load(), 3);
  EXPECT_FALSE(worker.push([] {}));
}

}  // namespace
}  // namespace mvis
