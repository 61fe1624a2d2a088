// SPDX-License-Identifier: Apache-2.0
// The one-set extension of the capture bundle (SetsRequired::OneOrBoth, read
// only by `cylscan phase`): a bundle with a single fringe set is refused by the
// default reader, as the contract says, and accepted with the option, which
// still refuses no set at all, unknown set names and frames of the absent set.
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "formats/capture_bundle.hpp"
#include "tests/formats/test_support.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;

using nlohmann::json;
using testing::readText;
using testing::throwsInputError;
using testing::writeText;

cv::Mat frameOf(int seed) {
  return cv::Mat(6, 8, CV_8UC1, cv::Scalar(10 + seed));
}

FringeSetInfo evenSet(double period_deg, int n, double start_deg) {
  FringeSetInfo set;
  set.period_deg = period_deg;
  for (int k = 0; k < n; ++k)
    set.stage_deg.push_back(start_deg + 0.2 * k);
  return set;
}

class OneSetBundleTest : public testing::TempDirTest {
 protected:
  fs::path bundle() const { return dir_ / "bundle"; }
  fs::path captureJson() const { return bundle() / "capture.json"; }

  // A two-set bundle (main: 4 high, 3 low frames, cam90 with its own sets)
  // written by the project's writer; frame k of a set has the value 10 + seed.
  void writeTwoSetBundle() const {
    CaptureInfo info;
    info.cameras = {"main", "cam90"};
    info.high = evenSet(5.0, 4, 236.0);
    info.low = evenSet(5.625, 3, 56.0);
    info.camera_sets["cam90"] = {evenSet(5.0, 4, 56.0), evenSet(5.625, 3, 236.0)};
    info.extra["sets"]["high"]["steps"] = json::array({1, 2, 3, 4});
    CaptureBundleWriter writer(bundle(), info);
    int seed = 0;
    for (const std::string& camera : info.cameras)
      for (const FringeSet id : kFringeSets)
        for (int k = 0; k < static_cast<int>(info.setOf(camera, id).stage_deg.size()); ++k)
          writer.writeFrame(camera, id, k, frameOf(seed++));
    writer.commit();
  }

  // The bundle without `set`: gone from capture.json ("sets" and every
  // "camera_sets" entry) and its frame directories removed.
  void removeSet(FringeSet set) const {
    json doc = json::parse(readText(captureJson()));
    const std::string name(toString(set));
    doc["sets"].erase(name);
    for (auto& [camera, sets] : doc["camera_sets"].items()) {
      sets.erase(name);
      fs::remove_all(bundle() / camera / name);
    }
    fs::remove_all(bundle() / "main" / name);
    writeJson(doc);
  }

  json readJson() const { return json::parse(readText(captureJson())); }
  void writeJson(const json& doc) const { writeText(captureJson(), doc.dump()); }

  ::testing::AssertionResult openFails(SetsRequired sets,
                                       std::initializer_list<std::string_view> needles) const {
    return throwsInputError([&] { CaptureBundleReader reader(bundle(), {}, sets); }, captureJson(),
                            needles);
  }
};

TEST_F(OneSetBundleTest, TheDefaultReaderRefusesABundleWithOnlyTheHighSet) {
  writeTwoSetBundle();
  removeSet(FringeSet::Low);
  EXPECT_TRUE(openFails(SetsRequired::Both, {"missing set \"low\" in \"sets\""}));
}

TEST_F(OneSetBundleTest, OneOrBothReadsABundleWithOnlyTheHighSet) {
  writeTwoSetBundle();
  removeSet(FringeSet::Low);
  const CaptureBundleReader reader(bundle(), {}, SetsRequired::OneOrBoth);
  const CaptureInfo& info = reader.info();
  EXPECT_TRUE(info.hasSet(FringeSet::High));
  EXPECT_FALSE(info.hasSet(FringeSet::Low));
  EXPECT_TRUE(info.hasSetOf("cam90", FringeSet::High));
  EXPECT_FALSE(info.hasSetOf("cam90", FringeSet::Low));
  EXPECT_EQ(reader.frameCount(FringeSet::High), 4);
  EXPECT_EQ(reader.frameCount(FringeSet::Low), 0);
  EXPECT_EQ(reader.frameCount("cam90", FringeSet::Low), 0);
  EXPECT_EQ(info.high.stage_deg, evenSet(5.0, 4, 236.0).stage_deg);
  EXPECT_EQ(reader.frameSize("main"), cv::Size(8, 6));
  // main's high frames were written first: seeds 0..3.
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(cv::norm(reader.readFrame("main", FringeSet::High, k), frameOf(k), cv::NORM_INF), 0)
        << k;
  }
  EXPECT_THROW((void)reader.readFrame("main", FringeSet::Low, 0), std::out_of_range);
  // The extras of the set that is there are kept.
  EXPECT_EQ(info.extra["sets"]["high"]["steps"], json::array({1, 2, 3, 4}));
}

TEST_F(OneSetBundleTest, OneOrBothReadsABundleWithOnlyTheLowSet) {
  writeTwoSetBundle();
  removeSet(FringeSet::High);
  EXPECT_TRUE(openFails(SetsRequired::Both, {"missing set \"high\" in \"sets\""}));
  const CaptureBundleReader reader(bundle(), {}, SetsRequired::OneOrBoth);
  EXPECT_FALSE(reader.info().hasSet(FringeSet::High));
  EXPECT_TRUE(reader.info().hasSet(FringeSet::Low));
  EXPECT_EQ(reader.frameCount(FringeSet::Low), 3);
  EXPECT_EQ(reader.frameSize("main"), cv::Size(8, 6));
}

TEST_F(OneSetBundleTest, OneOrBothStillReadsBothSets) {
  writeTwoSetBundle();
  const CaptureBundleReader reader(bundle(), {}, SetsRequired::OneOrBoth);
  EXPECT_TRUE(reader.info().hasSet(FringeSet::High));
  EXPECT_TRUE(reader.info().hasSet(FringeSet::Low));
  EXPECT_EQ(reader.frameCount(FringeSet::Low), 3);
}

TEST_F(OneSetBundleTest, OneOrBothRefusesABundleWithoutAnySet) {
  writeTwoSetBundle();
  json doc = readJson();
  doc["sets"] = json::object();
  writeJson(doc);
  EXPECT_TRUE(openFails(SetsRequired::OneOrBoth, {"neither set", "\"sets\""}));
}

TEST_F(OneSetBundleTest, OneOrBothRefusesACameraEntryWithoutAnySet) {
  writeTwoSetBundle();
  json doc = readJson();
  doc["camera_sets"]["cam90"] = json::object();
  writeJson(doc);
  EXPECT_TRUE(openFails(SetsRequired::OneOrBoth, {"neither set", "camera_sets.cam90"}));
}

TEST_F(OneSetBundleTest, OneOrBothRefusesUnknownSetNames) {
  writeTwoSetBundle();
  removeSet(FringeSet::Low);
  json doc = readJson();
  doc["sets"]["medium"] = doc["sets"]["high"];
  writeJson(doc);
  EXPECT_TRUE(openFails(SetsRequired::OneOrBoth, {"unknown fringe set \"medium\""}));
}

TEST_F(OneSetBundleTest, FramesOfTheAbsentSetAreRefused) {
  writeTwoSetBundle();
  removeSet(FringeSet::Low);
  writeText(bundle() / "main" / "low" / "00.png", "a frame the angle list does not have");
  EXPECT_TRUE(
      openFails(SetsRequired::OneOrBoth, {"fewer angles than frames", "sets.low.stage_deg"}));
}

TEST_F(OneSetBundleTest, TheWriterStillWritesBothSetsOnly) {
  CaptureInfo info;
  info.cameras = {"main"};
  info.high = evenSet(5.0, 4, 236.0);
  EXPECT_THROW(CaptureBundleWriter(bundle(), info), std::invalid_argument);
}

}  // namespace
}  // namespace cylscan::formats
