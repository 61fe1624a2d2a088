// SPDX-License-Identifier: Apache-2.0
#include "drivers/v4l2_logic.hpp"

#include <gtest/gtest.h>
#include <linux/videodev2.h>

namespace cylscan::drivers {
namespace {

TEST(V4l2Formats, NamesFourccs) {
  EXPECT_EQ(fourccName(V4L2_PIX_FMT_GREY), "GREY");
  EXPECT_EQ(fourccName(V4L2_PIX_FMT_Y10), "Y10 ");
  EXPECT_EQ(fourccName(v4l2_fourcc('A', 0x01, 'B', 0x7f)), "A?B?");
}

TEST(V4l2Formats, KnowsTheMonochromeFormats) {
  const auto grey = v4l2MonoFormat(V4L2_PIX_FMT_GREY);
  ASSERT_TRUE(grey);
  EXPECT_EQ(grey->packing, MonoPacking::U8);
  EXPECT_EQ(grey->bits, 8);
  for (auto [fourcc, bits] : {std::pair{V4L2_PIX_FMT_Y10, 10}, std::pair{V4L2_PIX_FMT_Y12, 12},
                              std::pair{V4L2_PIX_FMT_Y16, 16}}) {
    const auto f = v4l2MonoFormat(fourcc);
    ASSERT_TRUE(f) << fourccName(fourcc);
    EXPECT_EQ(f->packing, MonoPacking::U16LE);
    EXPECT_EQ(f->bits, bits);
    EXPECT_EQ(v4l2Fourcc(*f), fourcc);
  }
  const auto packed = v4l2MonoFormat(V4L2_PIX_FMT_Y10P);
  ASSERT_TRUE(packed);
  EXPECT_EQ(packed->packing, MonoPacking::Csi2P10);
  EXPECT_EQ(v4l2Fourcc(*packed), V4L2_PIX_FMT_Y10P);
  EXPECT_FALSE(v4l2MonoFormat(V4L2_PIX_FMT_YUYV));
  EXPECT_FALSE(v4l2MonoFormat(V4L2_PIX_FMT_SRGGB10));
  EXPECT_THROW(v4l2Fourcc(MonoFormat{"YUYV", MonoPacking::U8, 8}), std::invalid_argument);
}

// What a device that offers colour and mono formats is asked for.
TEST(V4l2Formats, ChoosesFromAnEnumeratedList) {
  std::vector<MonoFormat> offered;
  for (std::uint32_t f :
       {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_Y10P, V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_Y16}) {
    if (auto m = v4l2MonoFormat(f)) offered.push_back(*m);
  }
  ASSERT_EQ(offered.size(), 3U);
  EXPECT_EQ(offered[*chooseMonoFormat(offered, 10)].name, "Y10P");
  EXPECT_EQ(offered[*chooseMonoFormat(offered, 12)].name, "Y16 ");
  EXPECT_EQ(offered[*chooseMonoFormat(offered, 8)].name, "GREY");
}

TEST(V4l2Controls, ClampsToTheRangeAndItsStep) {
  const V4l2ControlRange r{10, 100, 5, 50};
  EXPECT_EQ(clampToRange(50, r).value, 50);
  EXPECT_FALSE(clampToRange(50, r).clamped);
  EXPECT_EQ(clampToRange(3, r).value, 10);
  EXPECT_TRUE(clampToRange(3, r).clamped);
  EXPECT_EQ(clampToRange(1000, r).value, 100);
  EXPECT_TRUE(clampToRange(1000, r).clamped);
  EXPECT_EQ(clampToRange(22, r).value, 20);  // the grid is 10, 15, 20, ...
  EXPECT_EQ(clampToRange(23, r).value, 25);
  EXPECT_TRUE(clampToRange(23, r).clamped);
  // A maximum off the grid: the last grid value below it.
  EXPECT_EQ(clampToRange(99, V4l2ControlRange{0, 99, 10, 0}).value, 90);
  // Step 0 (some drivers report it for integer controls) means 1.
  EXPECT_EQ(clampToRange(42, V4l2ControlRange{0, 100, 0, 0}).value, 42);
  EXPECT_THROW(clampToRange(1, V4l2ControlRange{5, 4, 1, 5}), std::invalid_argument);
}

TEST(V4l2Controls, ExposureIsInHundredMicroseconds) {
  EXPECT_EQ(exposureUsToV4l2(10000.0), 100);
  EXPECT_EQ(exposureUsToV4l2(149.0), 1);
  EXPECT_EQ(exposureUsToV4l2(151.0), 2);
  EXPECT_EQ(exposureUsToV4l2(20.0), 1);  // never 0: the shortest exposure
  EXPECT_DOUBLE_EQ(v4l2ExposureToUs(exposureUsToV4l2(12300.0)), 12300.0);
  EXPECT_THROW(exposureUsToV4l2(0.0), std::invalid_argument);
  EXPECT_THROW(exposureUsToV4l2(-5.0), std::invalid_argument);
}

TEST(V4l2Controls, GainScalesTheDriversDefault) {
  const V4l2ControlRange r{16, 248, 1, 16};
  EXPECT_EQ(gainToV4l2(1.0, r), 16);
  EXPECT_EQ(gainToV4l2(2.5, r), 40);
  EXPECT_EQ(clampToRange(gainToV4l2(100.0, r), r).value, 248);
  EXPECT_THROW(gainToV4l2(0.0, r), std::invalid_argument);
  // A control whose default is 0 (a dB scale) can only be left at it.
  const V4l2ControlRange db{0, 480, 1, 0};
  EXPECT_EQ(gainToV4l2(1.0, db), 0);
  EXPECT_THROW(gainToV4l2(2.0, db), std::invalid_argument);
}

TEST(V4l2Controls, ReportsTheExposureRangeInMicroseconds) {
  const V4l2ControlRange r{2, 3000, 1, 100};  // 200 µs to 300 ms
  const ControlRange c = v4l2ExposureControl(clampToRange(exposureUsToV4l2(12340.0), r).value, r);
  EXPECT_DOUBLE_EQ(c.value, 12300.0);  // what the device uses: whole 100 µs units
  EXPECT_DOUBLE_EQ(c.min, 200.0);
  EXPECT_DOUBLE_EQ(c.max, 300000.0);
  // A request beyond the range reports the value it was clamped to.
  EXPECT_DOUBLE_EQ(v4l2ExposureControl(clampToRange(exposureUsToV4l2(1e6), r).value, r).value,
                   300000.0);
  EXPECT_DOUBLE_EQ(v4l2ExposureControl(clampToRange(exposureUsToV4l2(20.0), r).value, r).value,
                   200.0);
}

TEST(V4l2Controls, ReportsTheGainAsAFactorOfTheDefault) {
  const V4l2ControlRange r{16, 248, 1, 16};
  const ControlRange c = v4l2GainControl(gainToV4l2(2.5, r), r);
  EXPECT_DOUBLE_EQ(c.value, 2.5);
  EXPECT_DOUBLE_EQ(c.min, 1.0);
  EXPECT_DOUBLE_EQ(c.max, 15.5);
  // The control's quantisation shows: 1.02 × 16 rounds to 16, unity.
  EXPECT_DOUBLE_EQ(v4l2GainControl(gainToV4l2(1.02, r), r).value, 1.0);
  EXPECT_DOUBLE_EQ(v4l2GainFactor(gainToV4l2(3.0, r), r), 3.0);
  // A range below the default: factors under 1.
  const V4l2ControlRange wide{0, 1023, 1, 64};
  const ControlRange w = v4l2GainControl(clampToRange(gainToV4l2(100.0, wide), wide).value, wide);
  EXPECT_DOUBLE_EQ(w.min, 0.0);
  EXPECT_DOUBLE_EQ(w.max, 1023.0 / 64.0);
  EXPECT_DOUBLE_EQ(w.value, w.max);
  // A default of 0 (a dB scale) has no unity to scale: only gain 1 is settable.
  const V4l2ControlRange db{0, 480, 1, 0};
  const ControlRange d = v4l2GainControl(gainToV4l2(1.0, db), db);
  EXPECT_DOUBLE_EQ(d.value, 1.0);
  EXPECT_DOUBLE_EQ(d.min, 1.0);
  EXPECT_DOUBLE_EQ(d.max, 1.0);
  EXPECT_THROW(v4l2GainFactor(0, db), std::invalid_argument);
}

TEST(V4l2Timestamps, ExposureStart) {
  using std::chrono::nanoseconds;
  EXPECT_EQ(exposureStart(nanoseconds(5'000'000'000), true, 10000.0), nanoseconds(5'000'000'000));
  EXPECT_EQ(exposureStart(nanoseconds(5'000'000'000), false, 10000.0), nanoseconds(4'990'000'000));
}

}  // namespace
}  // namespace cylscan::drivers
