// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <cstdint>
#include <string>

#include <opencv2/core/types.hpp>

namespace cylscan::formats {

// An image size as every error message spells it: "1000x800".
inline std::string sizeText(std::int64_t width, std::int64_t height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

inline std::string sizeText(cv::Size size) {
  return sizeText(size.width, size.height);
}

}  // namespace cylscan::formats
