// SPDX-License-Identifier: Apache-2.0
// The live view's pictures: a camera frame as the set-up page shows it, with
// the two figures a person aims, focuses and exposes by (the focus measure
// and the share of saturated pixels), as a JPEG from libjpeg-turbo's
// TurboJPEG API. The encoder runs for every frame of every open live view,
// so it is the field's SIMD codec rather than OpenCV's generic one.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>

#include <opencv2/core.hpp>

namespace cylscan::firmware {

class JpegError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// One TurboJPEG compressor. A handle is not to be shared between threads:
// each thread that encodes owns its encoder.
class JpegEncoder {
 public:
  // quality 1..100 (std::invalid_argument otherwise); JpegError when
  // TurboJPEG cannot make a compressor.
  explicit JpegEncoder(int quality = 85);
  ~JpegEncoder();
  JpegEncoder(JpegEncoder&&) noexcept;
  JpegEncoder& operator=(JpegEncoder&&) noexcept;
  JpegEncoder(const JpegEncoder&) = delete;
  JpegEncoder& operator=(const JpegEncoder&) = delete;

  // A CV_8UC1 image as a greyscale JPEG, a CV_8UC3 (BGR) one as a colour
  // JPEG (4:2:0). std::invalid_argument for another type or an empty image.
  std::string encode(const cv::Mat& image);

 private:
  struct Handle;
  std::unique_ptr<Handle> handle_;
  int quality_;
};

// What a frame says about the camera's set-up.
struct FrameMeasures {
  // The variance of the Laplacian over the central half of the picture (in
  // 8-bit counts²): larger when sharper, for the same scene and light.
  double focus = 0.0;
  // The share of pixels at the camera's full scale (2^bit_depth − 1).
  double saturated = 0.0;
};

// The frame's counts on an 8-bit scale: full scale 2^bit_depth − 1 → 255.
// A CV_8UC1 frame is returned as is (shared); CV_16UC1 is scaled.
// std::invalid_argument for another type or a bit depth outside 1..16.
cv::Mat eightBitPicture(const cv::Mat& frame, int bit_depth);

FrameMeasures measureFrame(const cv::Mat& frame, int bit_depth);

// The 8-bit picture in BGR with the saturated pixels painted pure red.
cv::Mat saturationOverlay(const cv::Mat& frame, int bit_depth);

struct LivePicture {
  std::string jpeg;
  FrameMeasures measures;
};

// The frame as the live view sends it: measured, overlaid when asked, encoded.
LivePicture livePicture(const cv::Mat& frame, int bit_depth, bool saturation_overlay,
                        JpegEncoder& encoder);

}  // namespace cylscan::firmware
