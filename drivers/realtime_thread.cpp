// SPDX-License-Identifier: Apache-2.0
#include "drivers/realtime_thread.hpp"

#include <pthread.h>
#include <sched.h>
#include <string.h>
#include <sys/mman.h>

#include <cerrno>
#include <future>
#include <stdexcept>
#include <system_error>

namespace cylscan::drivers {

namespace {

struct Setup {
  bool realtime = false;
  bool memory_locked = false;
  std::vector<std::string> warnings;
};

// Touches the 256 KB of this thread's stack below the caller's frame: once
// touched, its pages stay resident under mlockall.
void prefaultStack() {
  unsigned char stack[256 * 1024];
  // Not optimised away, unlike a memset of memory never read.
  explicit_bzero(stack, sizeof stack);
}

// Missing privilege: EPERM (no CAP_SYS_NICE / RLIMIT_RTPRIO, no
// CAP_IPC_LOCK) or ENOMEM/EAGAIN (RLIMIT_MEMLOCK below what is mapped).
Setup setUp(const RealtimeOptions& options) {
  Setup s;
  sched_param param{};
  param.sched_priority = options.priority;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
  if (rc == 0) {
    s.realtime = true;
  } else if (rc == EPERM) {
    s.warnings.push_back("real-time thread: SCHED_FIFO priority " +
                         std::to_string(options.priority) +
                         " not permitted (EPERM; needs CAP_SYS_NICE or RLIMIT_RTPRIO): running "
                         "at normal priority, step and trigger timing may jitter");
  } else {
    throw std::system_error(rc, std::generic_category(), "pthread_setschedparam(SCHED_FIFO)");
  }
  if (options.lock_memory) {
    // MCL_ONFAULT: a page is locked once touched, never made resident for
    // the lock's sake. Without it every mapping becomes resident, each
    // thread's whole 8 MB stack among them: more than half of a scan's peak
    // on the emulated board (docs/performance.md). This thread's own stack
    // is touched now, so that the steps' calls do not fault on it.
    int rc_lock = mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT);
    if (rc_lock != 0 && errno == EINVAL) {
      // A kernel before 4.4 has no MCL_ONFAULT: lock as it can.
      rc_lock = mlockall(MCL_CURRENT | MCL_FUTURE);
      if (rc_lock == 0) {
        s.warnings.push_back(
            "real-time thread: mlockall without MCL_ONFAULT (EINVAL: a kernel before 4.4): "
            "every mapping is resident, thread stacks whole");
      }
    }
    if (rc_lock == 0) {
      s.memory_locked = true;
      prefaultStack();
    } else {
      const int err = errno;
      if (err != EPERM && err != ENOMEM && err != EAGAIN) {
        throw std::system_error(err, std::generic_category(), "mlockall");
      }
      s.warnings.push_back(
          std::string("real-time thread: mlockall failed (") +
          (err == EPERM ? "EPERM; needs CAP_IPC_LOCK" : "ENOMEM; RLIMIT_MEMLOCK too low") +
          "): memory not locked, page faults may delay steps");
    }
  }
  return s;
}

}  // namespace

RealtimeThread::RealtimeThread(std::function<void()> body, RealtimeOptions options) {
  const int lo = sched_get_priority_min(SCHED_FIFO), hi = sched_get_priority_max(SCHED_FIFO);
  if (options.priority < lo || options.priority > hi) {
    throw std::invalid_argument("real-time thread: priority " + std::to_string(options.priority) +
                                " outside [" + std::to_string(lo) + ", " + std::to_string(hi) +
                                "]");
  }
  std::promise<Setup> ready;
  std::future<Setup> setup = ready.get_future();
  thread_ =
      std::thread([this, options, body = std::move(body), ready = std::move(ready)]() mutable {
        try {
          ready.set_value(setUp(options));
        } catch (...) {
          ready.set_exception(std::current_exception());
          return;
        }
        try {
          body();
        } catch (...) {
          error_ = std::current_exception();
        }
      });
  try {
    Setup s = setup.get();
    realtime_ = s.realtime;
    memory_locked_ = s.memory_locked;
    warnings_ = std::move(s.warnings);
  } catch (...) {
    thread_.join();
    throw;
  }
}

RealtimeThread::~RealtimeThread() {
  if (thread_.joinable()) thread_.join();
}

void RealtimeThread::join() {
  if (thread_.joinable()) thread_.join();
  if (error_) {
    std::exception_ptr e = error_;
    error_ = nullptr;
    std::rethrow_exception(e);
  }
}

}  // namespace cylscan::drivers
