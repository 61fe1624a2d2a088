// SPDX-License-Identifier: Apache-2.0
// The system report: the booted slot from the kernel command line, the host
// name and the data file system's size.
#include "firmware/daemon/system_info.hpp"

#include <unistd.h>

#include <array>

#include <gtest/gtest.h>

#include "tests/support/temp_dir.hpp"

namespace cylscan::firmware {
namespace {

using test_support::TempDir;

TEST(SystemInfo, TheBootedSlotIsReadFromTheKernelCommandLine) {
  EXPECT_EQ(bootedSlot("console=ttyAMA0 rauc.slot=a quiet\n"), "a");
  EXPECT_EQ(bootedSlot("rauc.slot=b"), "b");
  EXPECT_EQ(bootedSlot("root=/dev/vda2 quiet"), std::nullopt);
  EXPECT_EQ(bootedSlot("rauc.slot=c"), std::nullopt);  // not a slot of an image
  EXPECT_EQ(bootedSlot("xrauc.slot=a"), std::nullopt);
  EXPECT_EQ(bootedSlot(""), std::nullopt);
}

TEST(SystemInfo, OsReleaseValuesAreReadQuotedOrNot) {
  const std::string text =
      "PRETTY_NAME=\"Debian GNU/Linux 12 (bookworm)\"\nID=debian\n"
      "IMAGE_ID=cylscan-qemu-virt\nIMAGE_VERSION='1.2.3'\nIMAGE_VERSIONX=no\n";
  EXPECT_EQ(osReleaseValue(text, "IMAGE_ID"), "cylscan-qemu-virt");
  EXPECT_EQ(osReleaseValue(text, "IMAGE_VERSION"), "1.2.3");
  EXPECT_EQ(osReleaseValue(text, "PRETTY_NAME"), "Debian GNU/Linux 12 (bookworm)");
  EXPECT_EQ(osReleaseValue(text, "VERSION"), std::nullopt);
  EXPECT_EQ(osReleaseValue("", "ID"), std::nullopt);
}

TEST(SystemInfo, ReportsTheMachine) {
  TempDir dir;
  const auto cmdline = dir.write("cmdline", "console=ttyAMA0 rauc.slot=b\n");
  const auto release =
      dir.write("os-release", "ID=debian\nIMAGE_ID=cylscan-rpi5\nIMAGE_VERSION=\"2.0.1\"\n");
  const nlohmann::json r = SystemInfo("1.2.3", dir.path(), cmdline, release).report();
  EXPECT_EQ(r["version"], "1.2.3");
  EXPECT_EQ(r["slot"], "b");
  EXPECT_EQ(r["image"], (nlohmann::json{{"id", "cylscan-rpi5"}, {"version", "2.0.1"}}));
  std::array<char, 256> name{};
  ASSERT_EQ(gethostname(name.data(), name.size() - 1), 0);
  EXPECT_EQ(r["hostname"], std::string(name.data()));
  ASSERT_TRUE(r["data"].is_object());
  EXPECT_GT(r["data"]["total_bytes"].get<std::uint64_t>(), 0u);
  EXPECT_LE(r["data"]["free_bytes"].get<std::uint64_t>(),
            r["data"]["total_bytes"].get<std::uint64_t>());

  // Outside an image, and with a data folder that is gone.
  const nlohmann::json bare =
      SystemInfo("1.2.3", dir.path() / "gone", dir.path() / "no-cmdline", dir.path() / "none")
          .report();
  EXPECT_TRUE(bare["slot"].is_null());
  EXPECT_TRUE(bare["image"].is_null());
  EXPECT_TRUE(bare["data"].is_null());
}

}  // namespace
}  // namespace cylscan::firmware
