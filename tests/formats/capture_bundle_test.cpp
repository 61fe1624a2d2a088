// SPDX-License-Identifier: Apache-2.0
#include "formats/capture_bundle.hpp"

#include <opencv2/imgcodecs.hpp>

#include "formats/images.hpp"
#include "tests/formats/test_support.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;

using nlohmann::json;
using testing::craftedPng;
using testing::readText;
using testing::throwsInputError;
using testing::writeText;

cv::Mat randomFrame(cv::Size size, int type, int seed) {
  cv::Mat frame(size, type);
  cv::RNG rng(static_cast<std::uint64_t>(seed) + 1);
  rng.fill(frame, cv::RNG::UNIFORM, 0, type == CV_16UC1 ? 65536 : 256);
  return frame;
}

CaptureInfo makeInfo(std::vector<std::string> cameras, int n_high, int n_low) {
  CaptureInfo info;
  info.cameras = std::move(cameras);
  info.high.period_deg = 5.0;
  info.low.period_deg = 5.625;
  for (int k = 0; k < n_high; ++k)
    info.high.stage_deg.push_back(-90.0 + 0.2 * k);
  for (int k = 0; k < n_low; ++k)
    info.low.stage_deg.push_back(87.188 + 0.224 * k);
  return info;
}

class CaptureBundleTest : public testing::TempDirTest {
 protected:
  // Writes a whole bundle; returns the frames written, by camera, set and k.
  std::map<std::string, std::array<std::vector<cv::Mat>, 2>> writeBundle(
      const fs::path& dir, const CaptureInfo& info, int type = CV_8UC1,
      cv::Size size = cv::Size(8, 6)) {
    std::map<std::string, std::array<std::vector<cv::Mat>, 2>> frames;
    CaptureBundleWriter writer(dir, info);
    int seed = 0;
    for (const std::string& camera : info.cameras) {
      for (const FringeSet id : kFringeSets) {
        for (int k = 0; k < static_cast<int>(info.set(id).stage_deg.size()); ++k) {
          cv::Mat frame = randomFrame(size, type, seed++);
          writer.writeFrame(camera, id, k, frame);
          frames[camera][static_cast<std::size_t>(id)].push_back(frame);
        }
      }
    }
    writer.commit();
    return frames;
  }

  fs::path bundle() const { return dir_ / "bundle"; }
  fs::path captureJson() const { return bundle() / "capture.json"; }

  // A valid main-only bundle with 4 + 3 frames, whose capture.json the test then edits.
  void writeDefaultBundle() { writeBundle(bundle(), makeInfo({"main"}, 4, 3)); }

  json readJson() const { return json::parse(readText(captureJson())); }
  void writeJson(const json& doc) const { writeText(captureJson(), doc.dump()); }

  ::testing::AssertionResult openFails(const fs::path& file,
                                       std::initializer_list<std::string_view> needles) const {
    return throwsInputError([&] { CaptureBundleReader reader(bundle()); }, file, needles);
  }
};

bool samePixels(const cv::Mat& a, const cv::Mat& b) {
  return a.type() == b.type() && a.size() == b.size() && cv::norm(a, b, cv::NORM_INF) == 0;
}

TEST(FrameFileName, TwoDigitsBelowAHundredFramesMoreAbove) {
  EXPECT_EQ(frameFileName(0, 25), "00");
  EXPECT_EQ(frameFileName(24, 25), "24");
  EXPECT_EQ(frameFileName(2, 3), "02");
  EXPECT_EQ(frameFileName(5, 100), "005");
  EXPECT_EQ(frameFileName(99, 100), "099");
  EXPECT_EQ(frameFileName(120, 121), "120");
  EXPECT_EQ(frameFileName(42, 1000), "0042");
  EXPECT_THROW(frameFileName(3, 3), std::invalid_argument);
  EXPECT_THROW(frameFileName(-1, 3), std::invalid_argument);
}

TEST(FringeSetIdText, NamesTheSets) {
  EXPECT_EQ(toString(FringeSet::High), "high");
  EXPECT_EQ(toString(FringeSet::Low), "low");
}

TEST_F(CaptureBundleTest, RoundTripKeepsInfoAndPixels8Bit) {
  const CaptureInfo info = makeInfo({"main", "aux"}, 5, 4);
  const auto frames = writeBundle(bundle(), info);
  const CaptureBundleReader reader(bundle());
  EXPECT_EQ(reader.info().cameras, info.cameras);
  EXPECT_EQ(reader.info().high.period_deg, info.high.period_deg);
  EXPECT_EQ(reader.info().low.period_deg, info.low.period_deg);
  EXPECT_EQ(reader.info().high.stage_deg, info.high.stage_deg);  // exact: JSON keeps doubles
  EXPECT_EQ(reader.info().low.stage_deg, info.low.stage_deg);
  EXPECT_TRUE(reader.info().extra.empty()) << reader.info().extra.dump();
  EXPECT_TRUE(reader.hasCamera("aux"));
  EXPECT_FALSE(reader.hasCamera("side"));
  EXPECT_EQ(reader.frameCount(FringeSet::High), 5);
  EXPECT_EQ(reader.frameCount(FringeSet::Low), 4);
  EXPECT_EQ(reader.frameSize("main"), cv::Size(8, 6));
  EXPECT_EQ(reader.framePath("aux", FringeSet::Low, 3), bundle() / "aux" / "low" / "03.png");
  for (const auto& [camera, sets] : frames) {
    for (const FringeSet id : kFringeSets) {
      const auto& written = sets[static_cast<std::size_t>(id)];
      for (int k = 0; k < static_cast<int>(written.size()); ++k) {
        const cv::Mat frame = reader.readFrame(camera, id, k);
        EXPECT_EQ(frame.type(), CV_8UC1);
        EXPECT_TRUE(samePixels(frame, written[static_cast<std::size_t>(k)]))
            << camera << " " << toString(id) << " " << k;
      }
    }
  }
  const json doc = readJson();
  EXPECT_EQ(doc["format"], "cylscan-capture-1");
  EXPECT_EQ(doc["cameras"], json({"main", "aux"}));
  EXPECT_EQ(doc["sets"].size(), 2u);
}

TEST_F(CaptureBundleTest, RoundTrip16Bit) {
  const CaptureInfo info = makeInfo({"main"}, 3, 3);
  const auto frames = writeBundle(bundle(), info, CV_16UC1, cv::Size(13, 7));
  const CaptureBundleReader reader(bundle());
  const cv::Mat frame = reader.readFrame("main", FringeSet::Low, 2);
  EXPECT_EQ(frame.type(), CV_16UC1);
  EXPECT_TRUE(samePixels(frame, frames.at("main")[1][2]));
  double max_value = 0;
  cv::minMaxLoc(frame, nullptr, &max_value);
  EXPECT_GT(max_value, 255);  // really 16-bit content
}

TEST_F(CaptureBundleTest, MoreThanAHundredFramesUseThreeDigits) {
  const CaptureInfo info = makeInfo({"main"}, 101, 3);
  const auto frames = writeBundle(bundle(), info, CV_8UC1, cv::Size(4, 3));
  EXPECT_TRUE(fs::exists(bundle() / "main" / "high" / "000.png"));
  EXPECT_TRUE(fs::exists(bundle() / "main" / "high" / "100.png"));
  EXPECT_FALSE(fs::exists(bundle() / "main" / "high" / "00.png"));
  EXPECT_TRUE(fs::exists(bundle() / "main" / "low" / "02.png"));
  const CaptureBundleReader reader(bundle());
  EXPECT_EQ(reader.frameCount(FringeSet::High), 101);
  EXPECT_EQ(reader.framePath("main", FringeSet::High, 7), bundle() / "main" / "high" / "007.png");
  EXPECT_TRUE(
      samePixels(reader.readFrame("main", FringeSet::High, 100), frames.at("main")[0][100]));
}

TEST_F(CaptureBundleTest, ExtraJsonFieldsAreKeptThroughReadAndWrite) {
  writeDefaultBundle();
  json doc = readJson();
  doc["exposure_us"] = 800;
  doc["device"] = {{"name", "head-7"}, {"steps", json::array({1, 2})}};
  doc["sets"]["high"]["steps_per_frame"] = 12;
  writeJson(doc);

  const CaptureBundleReader reader(bundle());
  const json& extra = reader.info().extra;
  EXPECT_EQ(extra["exposure_us"], 800);
  EXPECT_EQ(extra["device"]["name"], "head-7");
  EXPECT_EQ(extra["sets"]["high"]["steps_per_frame"], 12);
  EXPECT_FALSE(extra.contains("format"));
  EXPECT_FALSE(extra.contains("cameras"));
  EXPECT_FALSE(extra["sets"]["high"].contains("stage_deg"));
  EXPECT_FALSE(extra["sets"].contains("low"));

  // Writing the info again keeps the extras next to the known fields.
  const fs::path copy = dir_ / "copy";
  CaptureBundleWriter writer(copy, reader.info());
  for (const FringeSet id : kFringeSets) {
    for (int k = 0; k < reader.frameCount(id); ++k) {
      writer.writeFrame("main", id, k, reader.readFrame("main", id, k));
    }
  }
  writer.commit();
  const json written = json::parse(readText(copy / "capture.json"));
  EXPECT_EQ(written["exposure_us"], 800);
  EXPECT_EQ(written["device"]["steps"], json::array({1, 2}));
  EXPECT_EQ(written["sets"]["high"]["steps_per_frame"], 12);
  EXPECT_EQ(written["sets"]["high"]["stage_deg"], doc["sets"]["high"]["stage_deg"]);
  EXPECT_EQ(written["format"], "cylscan-capture-1");
  const CaptureBundleReader again(copy);
  EXPECT_EQ(again.info().extra, reader.info().extra);
}

// ----------------------------------------------------------------------------- capture.json

TEST_F(CaptureBundleTest, MissingCaptureJson) {
  writeDefaultBundle();
  fs::remove(captureJson());
  EXPECT_TRUE(openFails(captureJson(), {"missing", "not a capture bundle"}));
}

TEST_F(CaptureBundleTest, MissingBundleDirectory) {
  EXPECT_TRUE(openFails(captureJson(), {"cannot open", "No such file"}));
}

TEST_F(CaptureBundleTest, TruncatedCaptureJson) {
  writeDefaultBundle();
  const std::string text = readText(captureJson());
  writeText(captureJson(), text.substr(0, text.size() / 2));
  EXPECT_TRUE(openFails(captureJson(), {"not valid JSON", "truncated"}));
}

TEST_F(CaptureBundleTest, EmptyCaptureJson) {
  writeDefaultBundle();
  writeText(captureJson(), "");
  EXPECT_TRUE(openFails(captureJson(), {"not valid JSON"}));
}

TEST_F(CaptureBundleTest, CaptureJsonNotAnObject) {
  writeDefaultBundle();
  writeText(captureJson(), "[1, 2]");
  EXPECT_TRUE(openFails(captureJson(), {"not a JSON object"}));
}

TEST_F(CaptureBundleTest, MissingFormat) {
  writeDefaultBundle();
  json doc = readJson();
  doc.erase("format");
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"missing \"format\"", "cylscan-capture-1"}));
}

TEST_F(CaptureBundleTest, WrongFormat) {
  writeDefaultBundle();
  json doc = readJson();
  doc["format"] = "cylscan-capture-2";
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"unsupported format \"cylscan-capture-2\""}));
}

TEST_F(CaptureBundleTest, FormatNotAString) {
  writeDefaultBundle();
  json doc = readJson();
  doc["format"] = 1;
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"format\"", "not a string"}));
}

TEST_F(CaptureBundleTest, MissingCameras) {
  writeDefaultBundle();
  json doc = readJson();
  doc.erase("cameras");
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"missing \"cameras\""}));
}

TEST_F(CaptureBundleTest, CamerasNotAList) {
  writeDefaultBundle();
  json doc = readJson();
  doc["cameras"] = "main";
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"cameras\" is a string", "not a list"}));
}

TEST_F(CaptureBundleTest, CameraNameNotAString) {
  writeDefaultBundle();
  json doc = readJson();
  doc["cameras"] = json::array({"main", 3});
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"cameras[1]\"", "not a string"}));
}

TEST_F(CaptureBundleTest, CamerasWithoutMain) {
  writeDefaultBundle();
  fs::rename(bundle() / "main", bundle() / "left");
  json doc = readJson();
  doc["cameras"] = json::array({"left"});
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"does not contain \"main\""}));
}

TEST_F(CaptureBundleTest, EmptyCameraList) {
  writeDefaultBundle();
  json doc = readJson();
  doc["cameras"] = json::array();
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"cameras\" is empty"}));
}

TEST_F(CaptureBundleTest, DuplicateCameraNames) {
  writeDefaultBundle();
  json doc = readJson();
  doc["cameras"] = json::array({"main", "main"});
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"main\" is listed twice"}));
}

TEST_F(CaptureBundleTest, CameraNameWithSlash) {
  writeDefaultBundle();
  json doc = readJson();
  doc["cameras"] = json::array({"main", "../main"});
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"../main\"", "single path component"}));
}

TEST_F(CaptureBundleTest, CameraNameDotDot) {
  writeDefaultBundle();
  json doc = readJson();
  doc["cameras"] = json::array({"main", ".."});
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"..\"", "not a directory name"}));
}

TEST_F(CaptureBundleTest, EmptyCameraName) {
  writeDefaultBundle();
  json doc = readJson();
  doc["cameras"] = json::array({"main", ""});
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"camera name \"\"", "is empty"}));
}

TEST_F(CaptureBundleTest, MissingSets) {
  writeDefaultBundle();
  json doc = readJson();
  doc.erase("sets");
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"missing \"sets\""}));
}

TEST_F(CaptureBundleTest, SetsNotAnObject) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"] = json::array();
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"sets\" is a array", "not an object"}));
}

TEST_F(CaptureBundleTest, MissingHighSet) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"].erase("high");
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"missing set \"high\""}));
}

TEST_F(CaptureBundleTest, MissingLowSet) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"].erase("low");
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"missing set \"low\""}));
}

TEST_F(CaptureBundleTest, UnknownSetName) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["medium"] = doc["sets"]["low"];
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"unknown fringe set \"medium\"", "exactly"}));
}

TEST_F(CaptureBundleTest, SetNotAnObject) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["low"] = 5;
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"sets.low\"", "not an object"}));
}

TEST_F(CaptureBundleTest, MissingPeriod) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["high"].erase("period_deg");
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"missing \"sets.high.period_deg\""}));
}

TEST_F(CaptureBundleTest, PeriodNotANumber) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["high"]["period_deg"] = "5";
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"sets.high.period_deg\"", "not a number"}));
}

TEST_F(CaptureBundleTest, PeriodZero) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["low"]["period_deg"] = 0;
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"sets.low.period_deg\"", "must be > 0"}));
}

TEST_F(CaptureBundleTest, PeriodNegative) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["low"]["period_deg"] = -5.0;
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"sets.low.period_deg\"", "must be > 0"}));
}

TEST_F(CaptureBundleTest, PeriodOverflowsToInfinity) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["high"]["period_deg"] = 123456.0;
  std::string text = doc.dump();
  text.replace(text.find("123456.0"), 8, "1e400");
  writeText(captureJson(), text);
  EXPECT_TRUE(openFails(captureJson(), {"not valid JSON", "number overflow", "1e400"}));
}

TEST_F(CaptureBundleTest, MissingStageAngles) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["low"].erase("stage_deg");
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"missing \"sets.low.stage_deg\""}));
}

TEST_F(CaptureBundleTest, StageAnglesNotAList) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["low"]["stage_deg"] = 1.5;
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"sets.low.stage_deg\" is a number", "not a list"}));
}

TEST_F(CaptureBundleTest, StageAngleString) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["high"]["stage_deg"][2] = "1.0";
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"sets.high.stage_deg[2]\" is a string", "not a number"}));
}

TEST_F(CaptureBundleTest, StageAngleNull) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["high"]["stage_deg"][1] = nullptr;
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"sets.high.stage_deg[1]\" is a null"}));
}

TEST_F(CaptureBundleTest, StageAngleBoolean) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["low"]["stage_deg"][0] = true;
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"sets.low.stage_deg[0]\" is a boolean"}));
}

TEST_F(CaptureBundleTest, StageAngleOverflowsToInfinity) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["low"]["stage_deg"][1] = 123456.0;
  std::string text = doc.dump();
  text.replace(text.find("123456.0"), 8, "-1e400");
  writeText(captureJson(), text);
  EXPECT_TRUE(openFails(captureJson(), {"not valid JSON", "number overflow", "-1e400"}));
}

TEST_F(CaptureBundleTest, FewerThanThreeFrames) {
  writeDefaultBundle();
  json doc = readJson();
  doc["sets"]["low"]["stage_deg"] = json::array({1.0, 2.0});
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"sets.low.stage_deg\" lists 2 frames", "at least 3"}));
}

TEST_F(CaptureBundleTest, FewerAnglesThanFrames) {
  writeDefaultBundle();  // high has 4 frames
  json doc = readJson();
  doc["sets"]["high"]["stage_deg"].erase(3);
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"fewer angles than frames", "lists 3 angles",
                                        (fs::path("main") / "high" / "03.png").string()}));
}

// ----------------------------------------------------------------------------- frames

TEST_F(CaptureBundleTest, MissingFrame) {
  writeDefaultBundle();
  const fs::path frame = bundle() / "main" / "low" / "01.png";
  fs::remove(frame);
  EXPECT_TRUE(openFails(frame, {"frame is missing", "lists 3 frames in set \"low\""}));
}

TEST_F(CaptureBundleTest, MissingSetDirectory) {
  writeDefaultBundle();
  fs::remove_all(bundle() / "main" / "low");
  EXPECT_TRUE(openFails(bundle() / "main" / "low" / "00.png", {"frame is missing"}));
}

TEST_F(CaptureBundleTest, FrameThatIsNotAPng) {
  writeDefaultBundle();
  const fs::path frame = bundle() / "main" / "high" / "02.png";
  writeText(frame, "this is not an image at all, just some text of some length");
  EXPECT_TRUE(openFails(frame, {"not a PNG file"}));
}

TEST_F(CaptureBundleTest, EmptyFrameFile) {
  writeDefaultBundle();
  const fs::path frame = bundle() / "main" / "high" / "02.png";
  writeText(frame, "");
  EXPECT_TRUE(openFails(frame, {"not a PNG file"}));
}

TEST_F(CaptureBundleTest, TruncatedFrame) {
  writeDefaultBundle();
  const fs::path frame = bundle() / "main" / "high" / "01.png";
  const std::string bytes = readText(frame);
  writeText(frame, bytes.substr(0, bytes.size() / 2));
  const CaptureBundleReader reader(bundle());  // the header is intact
  EXPECT_TRUE(throwsInputError([&] { reader.readFrame("main", FringeSet::High, 1); }, frame,
                               {"truncated PNG"}));
  EXPECT_NO_THROW(reader.readFrame("main", FringeSet::High, 0));
}

TEST_F(CaptureBundleTest, FrameCutInsideTheHeader) {
  writeDefaultBundle();
  const fs::path frame = bundle() / "main" / "low" / "00.png";
  writeText(frame, readText(frame).substr(0, 20));
  EXPECT_TRUE(openFails(frame, {"truncated PNG", "IHDR"}));
}

TEST_F(CaptureBundleTest, CorruptImageData) {
  writeDefaultBundle();
  const fs::path frame = bundle() / "main" / "low" / "02.png";
  writeText(frame, craftedPng(8, 6, 8, 0));  // valid header, IDAT of garbage
  const CaptureBundleReader reader(bundle());
  EXPECT_TRUE(throwsInputError([&] { reader.readFrame("main", FringeSet::Low, 2); }, frame,
                               {"corrupt PNG", "cannot decode"}));
}

TEST_F(CaptureBundleTest, ThreeChannelFrame) {
  writeDefaultBundle();
  const fs::path frame = bundle() / "main" / "high" / "03.png";
  writePng(frame, cv::Mat(6, 8, CV_8UC3, cv::Scalar(1, 2, 3)));
  EXPECT_TRUE(openFails(frame, {"3 channel", "single-channel"}));
}

TEST_F(CaptureBundleTest, PaletteFrame) {
  writeDefaultBundle();
  const fs::path frame = bundle() / "main" / "high" / "03.png";
  writeText(frame, craftedPng(8, 6, 8, 3));
  EXPECT_TRUE(openFails(frame, {"colour type 3", "single-channel"}));
}

TEST_F(CaptureBundleTest, OneBitFrame) {
  writeDefaultBundle();
  const fs::path frame = bundle() / "main" / "low" / "00.png";
  writeText(frame, craftedPng(8, 6, 1, 0));
  EXPECT_TRUE(openFails(frame, {"1-bit", "8-bit or 16-bit"}));
}

TEST_F(CaptureBundleTest, FrameOfAnotherSize) {
  // A bundle from another writer, without "frame_sizes": the first frame
  // sets the camera's size.
  writeDefaultBundle();
  json doc = readJson();
  doc.erase("frame_sizes");
  writeJson(doc);
  const fs::path frame = bundle() / "main" / "low" / "02.png";
  writePng(frame, cv::Mat(7, 8, CV_8UC1, cv::Scalar(9)));
  EXPECT_TRUE(openFails(frame, {"frame size 8x7", "8x6", "00.png"}));
}

TEST_F(CaptureBundleTest, TheWriterDeclaresEachCamerasFrameSize) {
  writeBundle(bundle(), makeInfo({"main", "aux"}, 3, 3));
  const json doc = readJson();
  EXPECT_EQ(doc.at("frame_sizes"), json::parse(R"({"main": [8, 6], "aux": [8, 6]})"));
  const CaptureBundleReader reader(bundle());
  EXPECT_EQ(reader.info().frame_sizes.at("aux"), cv::Size(8, 6));
  EXPECT_TRUE(reader.info().extra.empty()) << reader.info().extra.dump();
}

TEST_F(CaptureBundleTest, EveryFrameIsBoundByTheDeclaredSize) {
  // A tiny file whose header claims 8000x8000 (128 MB of 16-bit pixels,
  // within the global limits) in a bundle that declares 8x6 is refused from
  // its header, as is a first frame of another size.
  writeDefaultBundle();
  const fs::path first = bundle() / "main" / "high" / "00.png";
  writeText(first, craftedPng(8000, 8000, 16, 0));
  EXPECT_TRUE(openFails(first, {"frame size 8000x8000", "8x6", "frame_sizes.main"}));
  writeDefaultBundle();
  json doc = readJson();
  doc["frame_sizes"]["main"] = {8, 5};
  writeJson(doc);
  EXPECT_TRUE(openFails(first, {"frame size 8x6", "8x5", "frame_sizes.main"}));
}

TEST_F(CaptureBundleTest, DeclaredFrameSizesMustBeWholePositiveSizesOfListedCameras) {
  writeDefaultBundle();
  const json good = readJson();
  for (const char* bad :
       {R"([8])", R"([8, 0])", R"([8.5, 6])", R"("8x6")", R"([8, -6])", R"([8, 4294967296])"}) {
    json doc = good;
    doc["frame_sizes"]["main"] = json::parse(bad);
    writeJson(doc);
    EXPECT_TRUE(openFails(captureJson(), {"\"frame_sizes.main\"", "[width, height]"})) << bad;
  }
  json doc = good;
  doc["frame_sizes"]["aux"] = {8, 6};
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"frame_sizes\" has camera \"aux\""}));
  doc = good;
  doc["frame_sizes"] = json::array();
  writeJson(doc);
  EXPECT_TRUE(openFails(captureJson(), {"\"frame_sizes\" is a", "not an object"}));
}

TEST_F(CaptureBundleTest, PngHeaderClaimingAnAbsurdSizeIsRejectedBeforeDecoding) {
  writeDefaultBundle();
  const fs::path frame = bundle() / "main" / "high" / "00.png";
  writeText(frame, craftedPng(100000, 100000, 8, 0));
  EXPECT_TRUE(openFails(frame, {"100000x100000", "limit"}));
}

TEST_F(CaptureBundleTest, FrameLimitsAreConfigurable) {
  writeDefaultBundle();  // 8x6 frames
  FrameLimits limits;
  limits.max_pixels = 40;
  EXPECT_TRUE(throwsInputError([&] { CaptureBundleReader reader(bundle(), limits); },
                               bundle() / "main" / "high" / "00.png", {"8x6", "40 pixels"}));
}

TEST_F(CaptureBundleTest, UnknownCameraNamesCaptureJson) {
  writeDefaultBundle();
  const CaptureBundleReader reader(bundle());
  EXPECT_TRUE(throwsInputError([&] { reader.readFrame("aux", FringeSet::High, 0); }, captureJson(),
                               {"no camera \"aux\"", "cameras: main"}));
  EXPECT_THROW(reader.framePath("main", FringeSet::High, 4), std::out_of_range);
}

TEST_F(CaptureBundleTest, OtherFilesInTheBundleAreIgnored) {
  writeDefaultBundle();
  writeText(bundle() / "main" / "high" / "notes.txt", "hello");
  writeText(bundle() / "main" / "high" / "preview.png", "not a frame");
  writeText(bundle() / "thumbnail.png", "x");
  const CaptureBundleReader reader(bundle());
  EXPECT_EQ(reader.frameCount(FringeSet::High), 4);
}

// ----------------------------------------------------------------------------- writer

TEST_F(CaptureBundleTest, WriterRejectsFramesOfOtherTypes) {
  CaptureBundleWriter writer(bundle(), makeInfo({"main"}, 3, 3));
  EXPECT_THROW(writer.writeFrame("main", FringeSet::High, 0, cv::Mat(4, 4, CV_8UC3)),
               std::invalid_argument);
  EXPECT_THROW(writer.writeFrame("main", FringeSet::High, 0, cv::Mat(4, 4, CV_32FC1)),
               std::invalid_argument);
  EXPECT_THROW(writer.writeFrame("main", FringeSet::High, 0, cv::Mat()), std::invalid_argument);
  EXPECT_THROW(writer.writeFrame("aux", FringeSet::High, 0, cv::Mat(4, 4, CV_8UC1)),
               std::invalid_argument);
  EXPECT_THROW(writer.writeFrame("main", FringeSet::High, 3, cv::Mat(4, 4, CV_8UC1)),
               std::invalid_argument);
  writer.writeFrame("main", FringeSet::High, 0, cv::Mat(4, 4, CV_8UC1, cv::Scalar(0)));
  EXPECT_THROW(writer.writeFrame("main", FringeSet::High, 1, cv::Mat(4, 5, CV_8UC1)),
               std::invalid_argument);
  EXPECT_FALSE(fs::exists(bundle() / "main" / "high" / "01.png"));
}

TEST_F(CaptureBundleTest, WriterRejectsInvalidInfo) {
  EXPECT_THROW(CaptureBundleWriter(bundle(), makeInfo({"aux"}, 3, 3)), std::invalid_argument);
  EXPECT_THROW(CaptureBundleWriter(bundle(), makeInfo({"main"}, 2, 3)), std::invalid_argument);
  EXPECT_THROW(CaptureBundleWriter(bundle(), makeInfo({"main", "a/b"}, 3, 3)),
               std::invalid_argument);
  CaptureInfo info = makeInfo({"main"}, 3, 3);
  info.low.period_deg = 0;
  EXPECT_THROW(CaptureBundleWriter(bundle(), info), std::invalid_argument);
  info = makeInfo({"main"}, 3, 3);
  info.extra["sets"] = {{"medium", json::object()}};
  EXPECT_THROW(CaptureBundleWriter(bundle(), info), std::invalid_argument);
  EXPECT_FALSE(fs::exists(bundle()));
}

TEST_F(CaptureBundleTest, CommitNeedsEveryFrame) {
  CaptureBundleWriter writer(bundle(), makeInfo({"main"}, 3, 3));
  for (int k = 0; k < 3; ++k) {
    writer.writeFrame("main", FringeSet::High, k, cv::Mat(4, 4, CV_8UC1, cv::Scalar(k)));
  }
  EXPECT_THROW(writer.commit(), std::logic_error);
  EXPECT_FALSE(fs::exists(captureJson()));
}

TEST_F(CaptureBundleTest, RewritingABundleWithFewerFramesLeavesAWholeBundle) {
  writeBundle(bundle(), makeInfo({"main"}, 12, 3));
  const fs::path old_frame = bundle() / "main" / "high" / "11.png";
  ASSERT_TRUE(fs::exists(old_frame));
  {
    CaptureBundleWriter writer(bundle(), makeInfo({"main"}, 3, 3));
    EXPECT_FALSE(fs::exists(captureJson()));  // not whole while being rewritten
  }
  writeBundle(bundle(), makeInfo({"main"}, 5, 3));
  EXPECT_FALSE(fs::exists(old_frame));
  const CaptureBundleReader reader(bundle());
  EXPECT_EQ(reader.frameCount(FringeSet::High), 5);
}

}  // namespace
}  // namespace cylscan::formats
