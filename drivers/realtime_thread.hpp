// SPDX-License-Identifier: Apache-2.0
// A worker thread for the step/trigger executor: SCHED_FIFO at a given
// priority and the process's memory locked (mlockall), when allowed. Without
// the privilege (EPERM, or a memory-lock limit too low) it runs at normal
// priority and says so in warnings(); the library never prints.
#pragma once

#include <exception>
#include <functional>
#include <string>
#include <thread>
#include <vector>

namespace cylscan::drivers {

struct RealtimeOptions {
  int priority = 80;        // SCHED_FIFO priority, within sched_get_priority_min/max
  bool lock_memory = true;  // mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT), the whole process
};

class RealtimeThread {
 public:
  // Starts `body` on the new thread once its scheduling is set up; returns
  // after the setup, so realtime() and warnings() are known. Throws
  // std::invalid_argument for a priority out of range and std::system_error
  // for a setup failure other than a missing privilege.
  explicit RealtimeThread(std::function<void()> body, RealtimeOptions options = {});
  ~RealtimeThread();  // joins; an exception of the body is lost unless join() was called
  RealtimeThread(const RealtimeThread&) = delete;
  RealtimeThread& operator=(const RealtimeThread&) = delete;

  // Waits for the body; rethrows its exception.
  void join();

  bool realtime() const { return realtime_; }           // SCHED_FIFO granted
  bool memoryLocked() const { return memory_locked_; }  // mlockall succeeded
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  std::thread thread_;
  std::exception_ptr error_;
  bool realtime_ = false;
  bool memory_locked_ = false;
  std::vector<std::string> warnings_;
};

}  // namespace cylscan::drivers
