// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/event_hub.hpp"

#include <algorithm>
#include <deque>

namespace cylscan::firmware {

struct EventHub::Queue {
  std::mutex mutex;
  std::condition_variable cv;
  std::deque<HeadEvent> events;
  std::size_t capacity = 0;
  std::uint64_t dropped = 0;
  bool closed = false;

  void push(const HeadEvent& e) {
    {
      const std::lock_guard lock(mutex);
      if (closed) return;
      if (events.size() >= capacity) {
        events.pop_front();
        ++dropped;
      }
      events.push_back(e);
    }
    cv.notify_one();
  }
  void close() {
    {
      const std::lock_guard lock(mutex);
      closed = true;
    }
    cv.notify_all();
  }
};

class EventHub::Subscription final : public EventStream {
 public:
  explicit Subscription(std::shared_ptr<Queue> queue) : queue_(std::move(queue)) {}
  ~Subscription() override { queue_->close(); }  // the hub forgets it at its next publish

  std::optional<HeadEvent> next(std::chrono::milliseconds timeout) override {
    std::unique_lock lock(queue_->mutex);
    queue_->cv.wait_for(lock, timeout, [&] { return queue_->closed || !queue_->events.empty(); });
    if (queue_->events.empty()) return std::nullopt;  // closed streams still drain first
    HeadEvent e = std::move(queue_->events.front());
    queue_->events.pop_front();
    return e;
  }
  bool closed() const override {
    const std::lock_guard lock(queue_->mutex);
    return queue_->closed && queue_->events.empty();
  }
  std::uint64_t dropped() const override {
    const std::lock_guard lock(queue_->mutex);
    return queue_->dropped;
  }

 private:
  std::shared_ptr<Queue> queue_;
};

EventHub::EventHub(std::size_t queue_capacity)
    : capacity_(std::max<std::size_t>(1, queue_capacity)) {}

EventHub::~EventHub() {
  close();
}

std::uint64_t EventHub::publish(std::string name, nlohmann::json data) {
  std::vector<std::shared_ptr<Queue>> live;
  HeadEvent e;
  {
    const std::lock_guard lock(mutex_);
    if (closed_) return seq_;
    e = HeadEvent{++seq_, std::move(name), std::move(data)};
    std::erase_if(queues_, [&](const std::weak_ptr<Queue>& w) {
      auto q = w.lock();
      if (!q) return true;
      live.push_back(std::move(q));
      return false;
    });
  }
  for (const auto& q : live)
    q->push(e);
  return e.seq;
}

std::unique_ptr<EventStream> EventHub::subscribe(std::optional<HeadEvent> first) {
  auto queue = std::make_shared<Queue>();
  queue->capacity = capacity_;
  const std::lock_guard lock(mutex_);
  if (closed_) {
    queue->closed = true;
  } else {
    if (first) {
      first->seq = ++seq_;
      queue->events.push_back(std::move(*first));
    }
    queues_.push_back(queue);
  }
  return std::make_unique<Subscription>(std::move(queue));
}

void EventHub::close() {
  std::vector<std::shared_ptr<Queue>> live;
  {
    const std::lock_guard lock(mutex_);
    closed_ = true;
    for (const auto& w : queues_)
      if (auto q = w.lock()) live.push_back(std::move(q));
    queues_.clear();
  }
  for (const auto& q : live)
    q->close();
}

std::size_t EventHub::subscribers() const {
  const std::lock_guard lock(mutex_);
  return static_cast<std::size_t>(std::count_if(
      queues_.begin(), queues_.end(), [](const std::weak_ptr<Queue>& w) { return !w.expired(); }));
}

}  // namespace cylscan::firmware
