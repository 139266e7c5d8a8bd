// A thread that runs tasks one at a time, in the order they were pushed: the nodelet's estimator
// thread, so that a sensor callback hands its reading over and returns without waiting for a
// solve. push() never blocks on a running task. At most `max_tasks` wait; a push beyond that is
// refused (the caller counts and says it), so that an estimator slower than its sensors cannot
// grow without bound. The destructor finishes the running task, drops the waiting ones and joins.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>

namespace mvis {

class SerialWorker {
 public:
  explicit SerialWorker(std::size_t max_tasks);
  ~SerialWorker();
  SerialWorker(const SerialWorker&) = delete;
  SerialWorker& operator=(const SerialWorker&) = delete;

  // Queues `task`; false (not queued) when max_tasks are already waiting or after stop().
  bool push(std::function<void()> task);
  // Runs `task` after every task pushed before it and waits for it, at most `timeout_s`; false
  // when it was refused, dropped by stop() or did not finish in time (it still runs later).
  bool runAndWait(std::function<void()> task, double timeout_s);

  struct Backlog {
    std::size_t tasks = 0;    // waiting, not counting the running one
    double oldest_s = 0.0;    // how long the oldest waiting task has waited [s]
    std::size_t refused = 0;  // pushes refused since the start
  };
  Backlog backlog() const;

  // Finishes the running task, drops the waiting ones and joins; idempotent. Returns how many
  // were dropped.
  std::size_t stop();

 private:
  using Clock = std::chrono::steady_clock;
  void run();

  const std::size_t max_tasks_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::pair<Clock::time_point, std::function<void()>>> tasks_;
  std::size_t refused_ = 0;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace mvis
