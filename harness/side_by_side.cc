// Runs side by side (side_by_side.h).
#include "harness/side_by_side.h"

#include <algorithm>
#include <utility>

#include "model/interrupt.h"
#include "solver/progress.h"

namespace clothbench {

SideBySide::SideBySide(int workers) {
  for (int w = 0; w < workers; ++w) workers_.emplace_back([this] { Work(); });
}

SideBySide::~SideBySide() {
  Cancel(0);
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  for (std::thread& w : workers_) w.join();
}

std::size_t SideBySide::Submit(std::function<RunSummary()> run) {
  std::size_t i = 0;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    tasks_.emplace_back();
    tasks_.back().run = std::move(run);
    i = tasks_.size() - 1;
  }
  changed_.notify_all();
  return i;
}

void SideBySide::Compute(Task& t) {
  const ScopedCancel cancel(&t.cancel);
  try {
    t.result = t.run();
  } catch (...) {
    t.error = std::current_exception();
  }
}

void SideBySide::Work() {
  SetKernelThreads(1);
  const ScopedProgressMute mute;
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    changed_.wait(lock, [&] {
      while (next_ < tasks_.size() && tasks_[next_].state != State::kQueued) ++next_;  // cancelled ones
      return stopping_ || next_ < tasks_.size();
    });
    if (next_ >= tasks_.size()) return;  // stopping, nothing queued
    Task& t = tasks_[next_++];
    t.state = State::kRunning;
    lock.unlock();
    Compute(t);
    lock.lock();
    t.state = State::kDone;
    changed_.notify_all();
  }
}

RunSummary SideBySide::Take(std::size_t i) {
  std::unique_lock<std::mutex> lock(mutex_);
  Task& t = tasks_.at(i);
  if (workers_.empty() && t.state == State::kQueued) {
    // No workers: computed here, in order (every earlier queued run first).
    while (next_ <= i) {
      Task& u = tasks_[next_++];
      if (u.state != State::kQueued) continue;  // cancelled
      u.state = State::kRunning;
      lock.unlock();
      Compute(u);
      lock.lock();
      u.state = State::kDone;
    }
  }
  changed_.wait(lock, [&] { return t.state == State::kDone; });
  if (t.error) std::rethrow_exception(t.error);
  return std::move(t.result);
}

void SideBySide::Cancel(std::size_t first, std::size_t last) {
  const std::lock_guard<std::mutex> lock(mutex_);
  for (std::size_t k = first; k < std::min(last, tasks_.size()); ++k) {
    Task& t = tasks_[k];
    t.cancel.store(true, std::memory_order_relaxed);
    if (t.state != State::kQueued) continue;
    t.state = State::kDone;
    t.result.status = RunStatus::kTimeLimit;
    t.result.message = "cancelled before it started";
  }
  changed_.notify_all();
}

}  // namespace clothbench
