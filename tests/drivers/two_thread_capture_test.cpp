// SPDX-License-Identifier: Apache-2.0
// The acquisition's two threads under the virtual clock: the executor on a
// real-time thread runs a continuous sweep with triggers while a capture
// thread waits for both cameras' frames. Every frame arrives, in sequence,
// exposed at its trigger at the executed stage angle, and the virtual times
// are the same on every run.
#include <gtest/gtest.h>

#include <latch>
#include <thread>

#include "drivers/realtime_thread.hpp"
#include "drivers/rotation_stage.hpp"
#include "drivers_test_support.hpp"

namespace cylscan::drivers {
namespace {

using namespace std::chrono_literals;

struct Capture {
  std::vector<Frame> main, aux;
  std::vector<double> trigger_angles;
  std::vector<double> true_angles;  // the head's stage at each main exposure's trigger
  std::chrono::nanoseconds end{0};
  std::uint64_t missed = 0;
};

Capture runScan(int frames) {
  sim::VirtualHead head(test::smallHead(), test::planeScene());
  RotationStage stage(test::stageFor(head.config()), head.clock(), head.gpio(),
                      test::stageSpecs(true));
  auto trigger = head.gpio().requestOutput(test::spec("trigger"), false);
  auto light = head.gpio().requestOutput(test::spec("light"), true);
  Camera& main = head.camera("main");
  Camera& aux = head.camera("aux");
  for (Camera* cam : {&main, &aux}) {
    CameraConfig c;
    c.trigger = TriggerMode::GpioPulse;
    cam->configure(c);
    cam->start();
  }
  stage.enable();
  stage.home();
  SweepRequest r;
  r.speed_deg_s = 10;  // 50 steps = 0.2° = 20 ms between frames (10 ms exposure)
  r.range_steps = 50 * (frames - 1);
  for (int k = 0; k < frames; ++k)
    r.trigger_offsets.push_back(50 * k);
  const PreparedSweep sweep = stage.prepareSweep(5000, r);

  Capture out;
  std::latch ready(2);  // both threads attached before either acts
  RealtimeOptions rt;
  rt.priority = 10;
  rt.lock_memory = false;
  RealtimeThread executor(
      [&] {
        ClockThread participant(head.clock());
        ready.arrive_and_wait();
        stage.runSweep(sweep, *trigger);
      },
      rt);
  std::thread capture([&] {
    ClockThread participant(head.clock());
    ready.arrive_and_wait();
    for (int k = 0; k < frames; ++k) {
      for (auto [cam, list] : {std::pair{&main, &out.main}, std::pair{&aux, &out.aux}}) {
        std::optional<Frame> f = cam->waitFrame(1s);
        if (!f) return;
        list->push_back(std::move(*f));
      }
    }
  });
  capture.join();
  executor.join();
  const auto latency =
      std::chrono::nanoseconds{std::llround(head.config().cameras[0].trigger_latency_us * 1e3)};
  for (const Frame& f : out.main)
    out.true_angles.push_back(head.stage().angleAt(f.timestamp - latency));
  out.trigger_angles = sweep.trigger_angles_deg;
  out.end = head.clock().now();
  out.missed = head.missedTriggers("main") + head.missedTriggers("aux");
  EXPECT_EQ(stage.position(), head.stage().position());
  return out;
}

TEST(TwoThreadCapture, EveryFrameInSequenceAtTheExecutedAngle) {
  constexpr int kFrames = 8;
  const Capture a = runScan(kFrames);
  ASSERT_EQ(a.main.size(), static_cast<std::size_t>(kFrames));
  ASSERT_EQ(a.aux.size(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(a.missed, 0u);
  for (int k = 0; k < kFrames; ++k) {
    const auto i = static_cast<std::size_t>(k);
    EXPECT_EQ(a.main[i].sequence, i);
    EXPECT_EQ(a.aux[i].sequence, i);
    EXPECT_EQ(a.main[i].timestamp, a.aux[i].timestamp);  // one trigger line
    // The trigger comes with the step that completes its count: the stage
    // is exactly at the executed angle (no ringing at that instant).
    EXPECT_DOUBLE_EQ(a.true_angles[i], a.trigger_angles[i]);
    EXPECT_DOUBLE_EQ(a.trigger_angles[i], (5000 + 50 * k) / 250.0);
    if (k > 0) {  // 20 ms apart in virtual time (±1 ns of deadline rounding)
      EXPECT_NEAR(static_cast<double>((a.main[i].timestamp - a.main[i - 1].timestamp).count()),
                  20e6, 1.0);
      EXPECT_GT(cv::norm(a.main[i].image, a.main[i - 1].image, cv::NORM_L1), 0);  // it moved
    }
  }
  // Deterministic: the same virtual times, and the same images, again.
  const Capture b = runScan(kFrames);
  ASSERT_EQ(b.main.size(), a.main.size());
  EXPECT_EQ(b.end, a.end);
  for (std::size_t i = 0; i < a.main.size(); ++i) {
    EXPECT_EQ(b.main[i].timestamp, a.main[i].timestamp);
    EXPECT_EQ(cv::norm(b.main[i].image, a.main[i].image, cv::NORM_INF), 0);
  }
}

}  // namespace
}  // namespace cylscan::drivers
