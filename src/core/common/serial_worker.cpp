#include "mvis/common/serial_worker.h"

#include <chrono>
#include <future>
#include <memory>

namespace mvis {

SerialWorker::SerialWorker(std::size_t max_tasks)
    : max_tasks_(max_tasks), thread_([this] { run(); }) {}

SerialWorker::~SerialWorker() { stop(); }

bool SerialWorker::push(std::function<void()> task) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_ || tasks_.size() >= max_tasks_) {
      ++refused_;
      return false;
    }
    tasks_.emplace_back(Clock::now(), std::move(task));
  }
  wake_.notify_one();
  return true;
}

bool SerialWorker::runAndWait(std::function<void()> task, double timeout_s) {
  auto done = std::make_shared<std::promise<void>>();
  std::future<void> finished = done->get_future();
  if (!push([task = std::move(task), done] {
        task();
        done->set_value();
      })) {
    return false;
  }
  if (finished.wait_for(std::chrono::duration<double>(timeout_s)) != std::future_status::ready) {
    return false;
  }
  try {
    finished.get();  // a task dropped by stop() breaks its promise
    return true;
  } catch (const std::future_error&) {
    return false;
  }
}

SerialWorker::Backlog SerialWorker::backlog() const {
  std::lock_guard<std::mutex> lock(mutex_);
  Backlog out;
  out.tasks = tasks_.size();
  out.refused = refused_;
  if (!tasks_.empty()) {
    out.oldest_s = std::chrono::duration<double>(Clock::now() - tasks_.front().first).count();
  }
  return out;
}

std::size_t SerialWorker::stop() {
  std::size_t dropped = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    dropped = tasks_.size();
    tasks_.clear();
  }
  wake_.notify_one();
  if (thread_.joinable()) thread_.join();
  return dropped;
}

void SerialWorker::run() {
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !tasks_.empty(); });
      if (stopping_) return;
      task = std::move(tasks_.front().second);
      tasks_.pop_front();
    }
    task();
  }
}

}  // namespace mvis
