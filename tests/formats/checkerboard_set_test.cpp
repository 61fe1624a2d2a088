// SPDX-License-Identifier: Apache-2.0
#include "formats/checkerboard_set.hpp"

#include <nlohmann/json.hpp>

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

class CheckerboardSetTest : public testing::TempDirTest {
 protected:
  fs::path board() const { return dir_ / "board"; }
  fs::path infoFile() const { return board() / "checkerboard.json"; }

  void writeImage(const std::string& camera, const std::string& id, cv::Size size = {8, 6}) {
    fs::create_directories(board() / camera);
    writePng(board() / camera / (id + ".png"), cv::Mat(size, CV_8UC1, cv::Scalar(128)));
  }

  void writeValidBoard() {
    writeCheckerboardInfo(board(), CheckerboardInfo{10, 7, 12.0});
    for (const char* id : {"00", "01", "02"}) {
      writeImage("main", id);
      writeImage("aux", id);
    }
  }

  ::testing::AssertionResult readFails(const fs::path& file,
                                       std::initializer_list<std::string_view> needles) const {
    return throwsInputError([&] { readCheckerboardSet(board()); }, file, needles);
  }
};

TEST_F(CheckerboardSetTest, RoundTripOfTheInfo) {
  writeValidBoard();
  const json doc = json::parse(readText(infoFile()));
  EXPECT_EQ(doc, json({{"cols", 10}, {"rows", 7}, {"square_mm", 12.0}}));
  const CheckerboardSet set = readCheckerboardSet(board());
  EXPECT_EQ(set.board.cols, 10);
  EXPECT_EQ(set.board.rows, 7);
  EXPECT_EQ(set.board.square_mm, 12.0);
  ASSERT_EQ(set.pairs.size(), 3u);
  EXPECT_EQ(set.pairs[1].id, "01");
  EXPECT_EQ(set.pairs[1].main, board() / "main" / "01.png");
  EXPECT_EQ(set.pairs[1].aux, board() / "aux" / "01.png");
}

TEST_F(CheckerboardSetTest, PairsAreTheIdsInBothCamerasSortedByNumber) {
  writeCheckerboardInfo(board(), CheckerboardInfo{9, 6, 20.5});
  for (const char* id : {"10", "02", "9", "05", "100"})
    writeImage("main", id);
  for (const char* id : {"100", "05", "02", "10", "07", "9"})
    writeImage("aux", id);
  writeText(board() / "main" / "07.jpg", "not png");
  writeText(board() / "main" / "notes.png", "not a pair");
  writeText(board() / "aux" / "README", "x");
  const CheckerboardSet set = readCheckerboardSet(board());
  std::vector<std::string> ids;
  for (const auto& pair : set.pairs)
    ids.push_back(pair.id);
  EXPECT_EQ(ids, (std::vector<std::string>{"02", "05", "9", "10", "100"}));
}

TEST_F(CheckerboardSetTest, MissingInfoFile) {
  writeValidBoard();
  fs::remove(infoFile());
  EXPECT_TRUE(readFails(infoFile(), {"cannot open"}));
}

TEST_F(CheckerboardSetTest, TruncatedInfoFile) {
  writeValidBoard();
  writeText(infoFile(), "{\"cols\": 10, \"ro");
  EXPECT_TRUE(readFails(infoFile(), {"not valid JSON"}));
}

TEST_F(CheckerboardSetTest, InfoNotAnObject) {
  writeValidBoard();
  writeText(infoFile(), "[10, 7, 12]");
  EXPECT_TRUE(readFails(infoFile(), {"not a JSON object"}));
}

TEST_F(CheckerboardSetTest, MissingRows) {
  writeValidBoard();
  writeText(infoFile(), R"({"cols": 10, "square_mm": 12})");
  EXPECT_TRUE(readFails(infoFile(), {"missing \"rows\""}));
}

TEST_F(CheckerboardSetTest, ColsNotAnInteger) {
  writeValidBoard();
  writeText(infoFile(), R"({"cols": 10.5, "rows": 7, "square_mm": 12})");
  EXPECT_TRUE(readFails(infoFile(), {"\"cols\"", "not an integer"}));
}

TEST_F(CheckerboardSetTest, ColsAsString) {
  writeValidBoard();
  writeText(infoFile(), R"({"cols": "10", "rows": 7, "square_mm": 12})");
  EXPECT_TRUE(readFails(infoFile(), {"\"cols\" is a string", "not an integer"}));
}

TEST_F(CheckerboardSetTest, RowsTooSmall) {
  writeValidBoard();
  writeText(infoFile(), R"({"cols": 10, "rows": 1, "square_mm": 12})");
  EXPECT_TRUE(readFails(infoFile(), {"\"rows\" is 1", "2..1000"}));
}

TEST_F(CheckerboardSetTest, SquareSizeZero) {
  writeValidBoard();
  writeText(infoFile(), R"({"cols": 10, "rows": 7, "square_mm": 0})");
  EXPECT_TRUE(readFails(infoFile(), {"\"square_mm\"", "> 0"}));
}

TEST_F(CheckerboardSetTest, SquareSizeInfinite) {
  writeValidBoard();
  writeText(infoFile(), R"({"cols": 10, "rows": 7, "square_mm": 1e400})");
  EXPECT_TRUE(readFails(infoFile(), {"number overflow", "1e400"}));
}

TEST_F(CheckerboardSetTest, SquareSizeNotANumber) {
  writeValidBoard();
  writeText(infoFile(), R"({"cols": 10, "rows": 7, "square_mm": null})");
  EXPECT_TRUE(readFails(infoFile(), {"\"square_mm\" is a null", "not a number"}));
}

TEST_F(CheckerboardSetTest, MissingAuxDirectory) {
  writeValidBoard();
  fs::remove_all(board() / "aux");
  EXPECT_TRUE(readFails(board() / "aux", {"missing directory"}));
}

TEST_F(CheckerboardSetTest, NoPairs) {
  writeCheckerboardInfo(board(), CheckerboardInfo{10, 7, 12.0});
  writeImage("main", "00");
  writeImage("main", "01");
  writeImage("aux", "02");
  EXPECT_TRUE(readFails(board(), {"no image pairs", "2 images", "1 images"}));
}

TEST_F(CheckerboardSetTest, ImagesOfOneCameraWithDifferentSizes) {
  writeValidBoard();
  writeImage("aux", "02", cv::Size(8, 5));
  EXPECT_TRUE(readFails(board() / "aux" / "02.png", {"8x5", "8x6", "00.png"}));
}

TEST_F(CheckerboardSetTest, PairImageWithAbsurdHeader) {
  writeValidBoard();
  writeText(board() / "main" / "01.png", craftedPng(100000, 100000, 8, 0));
  EXPECT_TRUE(readFails(board() / "main" / "01.png", {"100000x100000"}));
}

TEST_F(CheckerboardSetTest, PairImageThatIsNotAPng) {
  writeValidBoard();
  writeText(board() / "aux" / "00.png", "JFIF....................................");
  EXPECT_TRUE(readFails(board() / "aux" / "00.png", {"not a PNG file"}));
}

TEST_F(CheckerboardSetTest, WriterRejectsAnInvalidBoard) {
  EXPECT_THROW(writeCheckerboardInfo(board(), CheckerboardInfo{1, 7, 12.0}), std::invalid_argument);
  EXPECT_THROW(writeCheckerboardInfo(board(), CheckerboardInfo{10, 7, -1.0}),
               std::invalid_argument);
  EXPECT_FALSE(fs::exists(infoFile()));
}

}  // namespace
}  // namespace cylscan::formats
