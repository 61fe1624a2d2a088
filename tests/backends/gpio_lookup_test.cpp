// SPDX-License-Identifier: Apache-2.0
#include "drivers/gpio_lookup.hpp"

#include <gtest/gtest.h>

namespace cylscan::drivers {
namespace {

// Two chips like a Raspberry Pi 5's: the header's lines on one, others on another.
std::vector<ChipLines> chips() {
  return {
      {"/dev/gpiochip0", "gpio-brcmstb@107d508500", {"", "PWR_GPIO", "CAM_GPIO0"}},
      {"/dev/gpiochip4",
       "pinctrl-rp1",
       {"ID_SDA", "ID_SCL", "GPIO2", "GPIO3", "GPIO4", "", "GPIO6"}},
  };
}

LineSpec named(const std::string& name, const std::string& role = "step") {
  LineSpec s;
  s.name = name;
  s.role = role;
  return s;
}

LineSpec at(const std::string& chip, int offset, const std::string& role = "home") {
  LineSpec s;
  s.chip = chip;
  s.offset = offset;
  s.role = role;
  return s;
}

std::string errorOf(const LineSpec& spec, const std::vector<ChipLines>& tables) {
  try {
    resolveLine(spec, tables);
  } catch (const GpioError& e) {
    return e.what();
  }
  ADD_FAILURE() << describeLine(spec) << " resolved";
  return {};
}

TEST(GpioLookup, FindsALineByNameOnAnyChip) {
  EXPECT_EQ(resolveLine(named("GPIO4"), chips()), (LineLocation{"/dev/gpiochip4", 4}));
  EXPECT_EQ(resolveLine(named("CAM_GPIO0"), chips()), (LineLocation{"/dev/gpiochip0", 2}));
}

TEST(GpioLookup, AnUnknownNameIsAnErrorNamingItAndItsRole) {
  const std::string what = errorOf(named("GPIO17", "step"), chips());
  EXPECT_NE(what.find("step line 'GPIO17'"), std::string::npos) << what;
  EXPECT_NE(what.find("not found"), std::string::npos) << what;
  EXPECT_NE(what.find("/dev/gpiochip4 (pinctrl-rp1)"), std::string::npos) << what;
}

TEST(GpioLookup, ANameOnTwoChipsIsAnErrorNamingBoth) {
  std::vector<ChipLines> tables = chips();
  tables[0].names[0] = "GPIO6";
  const std::string what = errorOf(named("GPIO6", "light"), tables);
  EXPECT_NE(what.find("light line 'GPIO6'"), std::string::npos) << what;
  EXPECT_NE(what.find("ambiguous"), std::string::npos) << what;
  EXPECT_NE(what.find("/dev/gpiochip0:0"), std::string::npos) << what;
  EXPECT_NE(what.find("/dev/gpiochip4:6"), std::string::npos) << what;
}

TEST(GpioLookup, UnnamedLinesAreNeverFoundByName) {
  EXPECT_NE(errorOf(named(""), chips()).find("give either"), std::string::npos);
}

TEST(GpioLookup, FindsALineByChipAndOffset) {
  // The chip by path, by device name or by label.
  EXPECT_EQ(resolveLine(at("/dev/gpiochip4", 5), chips()), (LineLocation{"/dev/gpiochip4", 5}));
  EXPECT_EQ(resolveLine(at("gpiochip4", 6), chips()), (LineLocation{"/dev/gpiochip4", 6}));
  EXPECT_EQ(resolveLine(at("pinctrl-rp1", 0), chips()), (LineLocation{"/dev/gpiochip4", 0}));
  EXPECT_EQ(resolveLine(at("gpiochip0", 1), chips()), (LineLocation{"/dev/gpiochip0", 1}));
}

TEST(GpioLookup, ChipAndOffsetFaults) {
  std::string what = errorOf(at("gpiochip9", 1), chips());
  EXPECT_NE(what.find("home line gpiochip9:1"), std::string::npos) << what;
  EXPECT_NE(what.find("no GPIO chip 'gpiochip9'"), std::string::npos) << what;
  what = errorOf(at("gpiochip0", 3), chips());
  EXPECT_NE(what.find("offset out of range"), std::string::npos) << what;
  EXPECT_NE(what.find("has 3 lines"), std::string::npos) << what;
  EXPECT_NE(errorOf(at("gpiochip0", -1), chips()).find("offset out of range"), std::string::npos);
  std::vector<ChipLines> tables = chips();
  tables[0].label = "pinctrl-rp1";
  what = errorOf(at("pinctrl-rp1", 0), tables);
  EXPECT_NE(what.find("ambiguous"), std::string::npos) << what;
}

TEST(GpioLookup, NameAndChipTogetherIsAnError) {
  LineSpec both = named("GPIO4");
  both.chip = "gpiochip4";
  both.offset = 4;
  EXPECT_NE(errorOf(both, chips()).find("either a line name or a chip"), std::string::npos);
}

TEST(GpioLookup, NoChipsAtAll) {
  const std::string what = errorOf(named("GPIO4"), {});
  EXPECT_NE(what.find("chips: none"), std::string::npos) << what;
}

TEST(GpioLookup, DescribesLines) {
  EXPECT_EQ(describeLine(named("GPIO17", "step")), "step line 'GPIO17'");
  EXPECT_EQ(describeLine(at("gpiochip0", 22, "enable")), "enable line gpiochip0:22");
  EXPECT_EQ(describeLine(named("x", "")), "line 'x'");
}

TEST(GpioLookup, ChipMatching) {
  const ChipLines chip{"/dev/gpiochip4", "pinctrl-rp1", {}};
  EXPECT_TRUE(chipMatches("/dev/gpiochip4", chip));
  EXPECT_TRUE(chipMatches("gpiochip4", chip));
  EXPECT_TRUE(chipMatches("pinctrl-rp1", chip));
  EXPECT_FALSE(chipMatches("gpiochip0", chip));
  EXPECT_FALSE(chipMatches("", chip));
  EXPECT_FALSE(chipMatches("", ChipLines{"/dev/gpiochip1", "", {}}));
}

}  // namespace
}  // namespace cylscan::drivers
