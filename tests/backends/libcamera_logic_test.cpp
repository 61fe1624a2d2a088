// SPDX-License-Identifier: Apache-2.0
#include "drivers/libcamera_logic.hpp"

#include <gtest/gtest.h>

namespace cylscan::drivers {
namespace {

TEST(LibcameraFormats, KnowsTheMonochromeRawFormats) {
  struct Case {
    const char* name;
    MonoPacking packing;
    int bits;
  };
  for (const Case& c :
       {Case{"R8", MonoPacking::U8, 8}, Case{"R10", MonoPacking::U16LE, 10},
        Case{"R12", MonoPacking::U16LE, 12}, Case{"R16", MonoPacking::U16LE, 16},
        Case{"R10_CSI2P", MonoPacking::Csi2P10, 10}, Case{"R12_CSI2P", MonoPacking::Csi2P12, 12}}) {
    const auto f = libcameraMonoFormat(c.name);
    ASSERT_TRUE(f) << c.name;
    EXPECT_EQ(f->name, c.name);
    EXPECT_EQ(f->packing, c.packing) << c.name;
    EXPECT_EQ(f->bits, c.bits) << c.name;
  }
  for (const char* colour : {"SBGGR10_CSI2P", "YUV420", "MONO_PISP_COMP1", "r8", ""}) {
    EXPECT_FALSE(libcameraMonoFormat(colour)) << colour;
  }
}

TEST(LibcameraFormats, ChoosesAmongARawStreamsFormats) {
  std::vector<MonoFormat> offered;
  for (const char* name : {"SBGGR10_CSI2P", "R10_CSI2P", "R10"}) {
    if (auto f = libcameraMonoFormat(name)) offered.push_back(*f);
  }
  EXPECT_EQ(offered[*chooseMonoFormat(offered, 10)].name, "R10");
  EXPECT_EQ(offered[*chooseMonoFormat(offered, 8)].name, "R10");
}

TEST(LibcameraControls, ClampsToKnownBounds) {
  EXPECT_DOUBLE_EQ(clampValue(5.0, 1.0, 16.0).value, 5.0);
  EXPECT_FALSE(clampValue(5.0, 1.0, 16.0).clamped);
  EXPECT_DOUBLE_EQ(clampValue(0.5, 1.0, 16.0).value, 1.0);
  EXPECT_TRUE(clampValue(0.5, 1.0, 16.0).clamped);
  EXPECT_DOUBLE_EQ(clampValue(20.0, 1.0, 16.0).value, 16.0);
  EXPECT_DOUBLE_EQ(clampValue(20.0, 1.0, std::nullopt).value, 20.0);
  EXPECT_DOUBLE_EQ(clampValue(-2.0, std::nullopt, 16.0).value, -2.0);
}

TEST(LibcameraControls, ReportsTheControlInfoBounds) {
  const ControlRange c = libcameraControl(5000.0, 14.0, 1e6);
  EXPECT_DOUBLE_EQ(c.value, 5000.0);
  EXPECT_DOUBLE_EQ(c.min, 14.0);
  EXPECT_DOUBLE_EQ(c.max, 1e6);
  // The value as clamped is what is reported.
  const ClampedValue gain = clampValue(40.0, 1.0, 16.0);
  EXPECT_DOUBLE_EQ(libcameraControl(gain.value, 1.0, 16.0).value, 16.0);
  // A bound the camera does not give: only the value is known to work.
  const ControlRange open = libcameraControl(2.0, 1.0, std::nullopt);
  EXPECT_DOUBLE_EQ(open.min, 1.0);
  EXPECT_DOUBLE_EQ(open.max, 2.0);
  const ControlRange none = libcameraControl(3.0, std::nullopt, std::nullopt);
  EXPECT_DOUBLE_EQ(none.min, 3.0);
  EXPECT_DOUBLE_EQ(none.max, 3.0);
  // Bounds out of order (a maximum of 0 for "unknown") are no range.
  const ControlRange odd = libcameraControl(100.0, 50.0, 0.0);
  EXPECT_DOUBLE_EQ(odd.min, 100.0);
  EXPECT_DOUBLE_EQ(odd.max, 100.0);
}

}  // namespace
}  // namespace cylscan::drivers
