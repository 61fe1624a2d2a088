// SPDX-License-Identifier: Apache-2.0
// Publish/subscribe of the head's events (HeadEvent): every subscriber has a
// bounded queue; a full queue drops its oldest event (counted), so publishing
// never blocks on a slow reader. close() ends every stream (shutdown).
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "firmware/daemon/head_service.hpp"

namespace cylscan::firmware {

class EventHub {
 public:
  explicit EventHub(std::size_t queue_capacity = 256);
  ~EventHub();  // closes every stream
  EventHub(const EventHub&) = delete;
  EventHub& operator=(const EventHub&) = delete;

  // Queues the event for every subscriber; its seq is the returned number.
  std::uint64_t publish(std::string name, nlohmann::json data);
  // A stream of the events published from now on, starting with `first`
  // when given (e.g. the current state; it gets the next seq).
  std::unique_ptr<EventStream> subscribe(std::optional<HeadEvent> first = std::nullopt);
  void close();
  std::size_t subscribers() const;

 private:
  struct Queue;
  class Subscription;
  mutable std::mutex mutex_;
  std::size_t capacity_;
  std::uint64_t seq_ = 0;
  bool closed_ = false;
  std::vector<std::weak_ptr<Queue>> queues_;
};

}  // namespace cylscan::firmware
