// SPDX-License-Identifier: Apache-2.0
// Image files: 32-bit float TIFF maps and 8/16-bit PNG, written atomically.
#pragma once

#include <filesystem>

#include <opencv2/core.hpp>

namespace cylscan::formats {

// Writers throw std::invalid_argument for an image of another type, and
// std::system_error (see atomic_file.hpp) when the file cannot be written.
// For a safe PNG reader (header checked before decoding) see formats/png.hpp.
void writeFloatTiff(const std::filesystem::path& file, const cv::Mat& map);  // CV_32FC1
cv::Mat readFloatTiff(const std::filesystem::path& file);                    // InputError
void writePng(const std::filesystem::path& file, const cv::Mat& image);      // 8/16-bit, 1 or 3 ch

}  // namespace cylscan::formats
