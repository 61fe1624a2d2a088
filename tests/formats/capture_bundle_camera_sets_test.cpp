// SPDX-License-Identifier: Apache-2.0
// The capture bundle's "camera_sets" extension (a ring scan's cameras, each
// with its own sets): written and read back per camera, validated like the
// top-level sets, and bundles without it read as the plain format.
#include <functional>
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

FringeSetInfo evenSet(double period_deg, int n, double start_deg) {
  FringeSetInfo set;
  set.period_deg = period_deg;
  for (int k = 0; k < n; ++k)
    set.stage_deg.push_back(start_deg + 0.2 * k);
  return set;
}

// main and cam90 share the sweep angles, in swapped roles: cam90's high set is
// main's second sweep, its low set main's first. cam180 has 5 frames per set.
CaptureInfo ringInfo() {
  CaptureInfo info;
  info.cameras = {"main", "cam90", "cam180"};
  info.high = evenSet(5.0, 4, 236.0);
  info.low = evenSet(5.625, 4, 56.0);
  info.camera_sets["cam90"] = {evenSet(5.0, 4, 56.0), evenSet(5.625, 4, 236.0)};
  info.camera_sets["cam180"] = {evenSet(5.0, 5, 10.0), evenSet(5.625, 5, 190.0)};
  return info;
}

cv::Mat frameOf(int seed) {
  return cv::Mat(6, 8, CV_8UC1, cv::Scalar(10 + seed));
}

class CameraSetsTest : public testing::TempDirTest {
 protected:
  fs::path bundle() const { return dir_ / "bundle"; }
  fs::path captureJson() const { return bundle() / "capture.json"; }

  void write(const CaptureInfo& info) const {
    CaptureBundleWriter writer(bundle(), info);
    int seed = 0;
    for (const std::string& camera : info.cameras)
      for (const FringeSet id : kFringeSets)
        for (int k = 0; k < static_cast<int>(info.setOf(camera, id).stage_deg.size()); ++k)
          writer.writeFrame(camera, id, k, frameOf(seed++));
    writer.commit();
  }
  json readJson() const { return json::parse(readText(captureJson())); }
  void writeJson(const json& doc) const { writeText(captureJson(), doc.dump()); }
  ::testing::AssertionResult openFails(const fs::path& file,
                                       std::initializer_list<std::string_view> needles) const {
    return throwsInputError([&] { CaptureBundleReader reader(bundle()); }, file, needles);
  }
};

TEST_F(CameraSetsTest, EachCameraReadsItsOwnSets) {
  const CaptureInfo info = ringInfo();
  write(info);
  const json doc = readJson();
  // Top-level sets are main's; the extension holds only the cameras that differ.
  EXPECT_EQ(doc["sets"]["high"]["stage_deg"], json(info.high.stage_deg));
  ASSERT_TRUE(doc.contains("camera_sets"));
  EXPECT_EQ(doc["camera_sets"].size(), 2u);
  EXPECT_EQ(doc["camera_sets"]["cam90"]["low"]["period_deg"], 5.625);
  EXPECT_FALSE(doc["camera_sets"].contains("main"));

  const CaptureBundleReader reader(bundle());
  EXPECT_TRUE(reader.info().extra.empty()) << reader.info().extra.dump();
  EXPECT_FALSE(reader.info().hasOwnSets("main"));
  EXPECT_TRUE(reader.info().hasOwnSets("cam90"));
  for (const std::string& camera : info.cameras) {
    for (const FringeSet id : kFringeSets) {
      EXPECT_EQ(reader.info().setOf(camera, id).stage_deg, info.setOf(camera, id).stage_deg)
          << camera << " " << toString(id);  // exact: JSON keeps doubles
      EXPECT_EQ(reader.info().setOf(camera, id).period_deg, info.setOf(camera, id).period_deg);
    }
  }
  EXPECT_EQ(reader.info().setOf("cam90", FringeSet::High).stage_deg.front(), 56.0);
  EXPECT_EQ(reader.frameCount(FringeSet::High), 4);
  EXPECT_EQ(reader.frameCount("cam180", FringeSet::High), 5);
  EXPECT_EQ(reader.framePath("cam180", FringeSet::Low, 4), bundle() / "cam180" / "low" / "04.png");
  EXPECT_THROW((void)reader.framePath("main", FringeSet::Low, 4), std::out_of_range);
  EXPECT_EQ(
      cv::norm(reader.readFrame("cam180", FringeSet::Low, 4), frameOf(8 + 8 + 5 + 4), cv::NORM_INF),
      0);
  EXPECT_THROW((void)reader.frameCount("side", FringeSet::High), InputError);
}

TEST_F(CameraSetsTest, ExtrasInsideACamerasSetsSurviveARewrite) {
  write(ringInfo());
  json doc = readJson();
  doc["camera_sets"]["cam90"]["high"]["steps"] = json::array({1, 2, 3, 4});
  doc["plan"] = "ring";
  writeJson(doc);
  const CaptureBundleReader reader(bundle());
  EXPECT_EQ(reader.info().extra["camera_sets"]["cam90"]["high"]["steps"].size(), 4u);
  EXPECT_FALSE(reader.info().extra["camera_sets"]["cam90"]["high"].contains("stage_deg"));
  EXPECT_EQ(reader.info().extra["plan"], "ring");

  const fs::path copy = dir_ / "copy";
  {
    CaptureBundleWriter writer(copy, reader.info());
    for (const std::string& camera : reader.info().cameras)
      for (const FringeSet id : kFringeSets)
        for (int k = 0; k < reader.frameCount(camera, id); ++k)
          writer.writeFrame(camera, id, k, reader.readFrame(camera, id, k));
    writer.commit();
  }
  const CaptureBundleReader again(copy);
  EXPECT_EQ(again.info().extra, reader.info().extra);
  EXPECT_EQ(again.info().setOf("cam90", FringeSet::Low).stage_deg,
            reader.info().setOf("cam90", FringeSet::Low).stage_deg);
}

TEST_F(CameraSetsTest, ABundleWithoutTheExtensionReadsAsBefore) {
  CaptureInfo info = ringInfo();
  info.camera_sets.clear();
  info.cameras = {"main", "aux"};
  write(info);
  EXPECT_FALSE(readJson().contains("camera_sets"));
  const CaptureBundleReader reader(bundle());
  EXPECT_TRUE(reader.info().camera_sets.empty());
  EXPECT_EQ(&reader.info().setOf("aux", FringeSet::High), &reader.info().high);
  EXPECT_EQ(reader.frameCount("aux", FringeSet::Low), reader.frameCount(FringeSet::Low));
}

TEST_F(CameraSetsTest, ACamerasCountMustMatchItsFrames) {
  write(ringInfo());
  json doc = readJson();
  doc["camera_sets"]["cam180"]["low"]["stage_deg"].erase(4);
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"fewer angles than frames",
                                        "\"camera_sets.cam180.low.stage_deg\" lists 4 angles",
                                        (fs::path("cam180") / "low" / "04.png").string()}));
  doc["camera_sets"]["cam180"]["low"]["stage_deg"].push_back(11.0);
  doc["camera_sets"]["cam180"]["low"]["stage_deg"].push_back(12.0);
  writeJson(doc);
  EXPECT_TRUE(openFails(bundle() / "cam180" / "low" / "05.png",
                        {"frame is missing", "in set \"low\" of \"camera_sets.cam180\""}));
}

TEST_F(CameraSetsTest, ACamerasSetsAreValidatedLikeTheTopLevelOnes) {
  write(ringInfo());
  const json good = readJson();
  struct Case {
    const char* what;
    std::function<void(json&)> edit;
    std::vector<std::string> needles;
  };
  const std::vector<Case> cases = {
      {"not an object",
       [](json& d) { d["camera_sets"] = json::array(); },
       {"\"camera_sets\" is a array"}},
      {"unknown camera",
       [](json& d) { d["camera_sets"]["side"] = d["camera_sets"]["cam90"]; },
       {"\"camera_sets\" has camera \"side\"", "not in \"cameras\""}},
      {"main's own sets",
       [](json& d) { d["camera_sets"]["main"] = d["camera_sets"]["cam90"]; },
       {"\"camera_sets\" has camera \"main\"", "top-level \"sets\""}},
      {"camera entry not an object",
       [](json& d) { d["camera_sets"]["cam90"] = 3; },
       {"\"camera_sets.cam90\" is a number"}},
      {"unknown set",
       [](json& d) { d["camera_sets"]["cam90"]["mid"] = json::object(); },
       {"unknown fringe set \"mid\" in \"camera_sets.cam90\""}},
      {"missing set",
       [](json& d) { d["camera_sets"]["cam90"].erase("low"); },
       {"missing set \"low\" in \"camera_sets.cam90\""}},
      {"missing period",
       [](json& d) { d["camera_sets"]["cam90"]["high"].erase("period_deg"); },
       {"missing \"camera_sets.cam90.high.period_deg\""}},
      {"zero period",
       [](json& d) { d["camera_sets"]["cam90"]["high"]["period_deg"] = 0; },
       {"\"camera_sets.cam90.high.period_deg\"", "> 0"}},
      {"angle not a number",
       [](json& d) { d["camera_sets"]["cam90"]["low"]["stage_deg"][2] = "x"; },
       {"\"camera_sets.cam90.low.stage_deg[2]\" is a string"}},
      {"too few frames",
       [](json& d) {
         d["camera_sets"]["cam90"]["low"]["stage_deg"] = json::array({1.0, 2.0});
       },
       {"\"camera_sets.cam90.low.stage_deg\" lists 2 frames", "at least 3"}},
  };
  for (const Case& c : cases) {
    json doc = good;
    c.edit(doc);
    writeJson(doc);
    try {
      CaptureBundleReader reader(bundle());
      ADD_FAILURE() << c.what << ": opened";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), captureJson()) << c.what;
      for (const std::string& needle : c.needles)
        EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
            << c.what << ": " << e.what();
    }
  }
  // A number that overflows is refused, as in the top-level sets.
  json doc = good;
  doc["camera_sets"]["cam90"]["high"]["period_deg"] = 123456.0;
  std::string text = doc.dump();
  text.replace(text.find("123456.0"), 8, "1e400");
  writeText(captureJson(), text);
  EXPECT_TRUE(openFails(captureJson(), {"number overflow", "1e400"}));
}

TEST_F(CameraSetsTest, TheWriterRefusesCameraSetsOfUnknownCamerasOrBadSets) {
  CaptureInfo info = ringInfo();
  info.camera_sets["side"] = info.camera_sets["cam90"];
  EXPECT_THROW(CaptureBundleWriter(bundle(), info), std::invalid_argument);
  info = ringInfo();
  info.camera_sets["main"] = info.camera_sets["cam90"];  // main's sets are the top-level ones
  EXPECT_THROW(CaptureBundleWriter(bundle(), info), std::invalid_argument);
  info = ringInfo();
  info.camera_sets["cam90"].low.stage_deg.resize(2);
  EXPECT_THROW(CaptureBundleWriter(bundle(), info), std::invalid_argument);
  info = ringInfo();
  info.extra["camera_sets"] = {{"main", {{"high", json::object()}}}};  // main has no own sets
  EXPECT_THROW(CaptureBundleWriter(bundle(), info), std::invalid_argument);
  EXPECT_FALSE(fs::exists(bundle()));
  // Frames beyond a camera's own count are refused.
  CaptureBundleWriter writer(bundle(), ringInfo());
  EXPECT_NO_THROW(writer.writeFrame("cam180", FringeSet::High, 4, frameOf(0)));
  EXPECT_THROW(writer.writeFrame("main", FringeSet::High, 4, frameOf(0)), std::invalid_argument);
}

}  // namespace
}  // namespace cylscan::formats
