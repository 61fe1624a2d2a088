// SPDX-License-Identifier: Apache-2.0
// The checkerboard set for stereo calibration (docs/formats.md, checkerboard set).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace cylscan::formats {

struct CheckerboardInfo {
  int cols = 0;  // inner corners (OpenCV pattern size)
  int rows = 0;
  double square_mm = 0;
};

struct CheckerboardPair {
  std::string id;  // "NN"
  std::filesystem::path main;
  std::filesystem::path aux;
};

struct CheckerboardSet {
  CheckerboardInfo board;
  std::vector<CheckerboardPair> pairs;  // sorted by id; only ids present in both cameras
};

// InputError on: a missing/unparseable checkerboard.json; cols/rows not integers
// in [2, 1000]; square_mm not a finite number > 0; a missing main/ or aux/
// directory; no NN.png present in both; a pair image whose PNG header is not
// valid or claims an absurd size; images of one camera of different sizes.
// Files that are not NN.png, or present in one camera only, are ignored. Pairs
// are sorted by the number NN (then by name). Images are not decoded here.
CheckerboardSet readCheckerboardSet(const std::filesystem::path& dir);  // InputError
// Creates dir if needed and writes dir/checkerboard.json atomically;
// std::invalid_argument if the info breaks the rules above.
void writeCheckerboardInfo(const std::filesystem::path& dir, const CheckerboardInfo& info);

}  // namespace cylscan::formats
