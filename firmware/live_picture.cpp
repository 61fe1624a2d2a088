// SPDX-License-Identifier: Apache-2.0
#include "firmware/live_picture.hpp"

#include <turbojpeg.h>

#include <opencv2/imgproc.hpp>

namespace cylscan::firmware {

struct JpegEncoder::Handle {
  tjhandle tj = nullptr;
  Handle() : tj(tjInitCompress()) {
    if (tj == nullptr)
      throw JpegError(std::string("cannot start a JPEG compressor: ") + tjGetErrorStr2(nullptr));
  }
  ~Handle() { tjDestroy(tj); }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
};

JpegEncoder::JpegEncoder(int quality) : quality_(quality) {
  if (quality < 1 || quality > 100)
    throw std::invalid_argument("JPEG quality must be in 1..100, not " + std::to_string(quality));
  handle_ = std::make_unique<Handle>();
}

JpegEncoder::~JpegEncoder() = default;
JpegEncoder::JpegEncoder(JpegEncoder&&) noexcept = default;
JpegEncoder& JpegEncoder::operator=(JpegEncoder&&) noexcept = default;

std::string JpegEncoder::encode(const cv::Mat& image) {
  if (image.empty()) throw std::invalid_argument("JPEG: the image is empty");
  int format = 0;
  int subsampling = 0;
  if (image.type() == CV_8UC1) {
    format = TJPF_GRAY;
    subsampling = TJSAMP_GRAY;
  } else if (image.type() == CV_8UC3) {
    format = TJPF_BGR;
    subsampling = TJSAMP_420;
  } else {
    throw std::invalid_argument("JPEG: only 8-bit grey or BGR images are encoded");
  }
  unsigned char* out = nullptr;  // TurboJPEG's buffer, grown as it needs
  unsigned long size = 0;        // NOLINT(google-runtime-int): TurboJPEG's type
  const int pitch = static_cast<int>(image.step[0]);
  const int r = tjCompress2(handle_->tj, image.ptr<unsigned char>(), image.cols, pitch, image.rows,
                            format, &out, &size, subsampling, quality_, TJFLAG_FASTDCT);
  struct Free {
    unsigned char* p;
    ~Free() { tjFree(p); }
  } free_out{out};
  if (r != 0)
    throw JpegError(std::string("JPEG compression failed: ") + tjGetErrorStr2(handle_->tj));
  return {reinterpret_cast<const char*>(out), static_cast<std::size_t>(size)};
}

namespace {

void checkFrame(const cv::Mat& frame, int bit_depth) {
  if (frame.empty()) throw std::invalid_argument("live picture: the frame is empty");
  if (frame.type() != CV_8UC1 && frame.type() != CV_16UC1)
    throw std::invalid_argument("live picture: frames are 8- or 16-bit greyscale");
  const int container = frame.type() == CV_8UC1 ? 8 : 16;
  if (bit_depth < 1 || bit_depth > container)
    throw std::invalid_argument("live picture: bit depth " + std::to_string(bit_depth) +
                                " does not fit the frame's " + std::to_string(container) + " bits");
}

double fullScale(int bit_depth) {
  return static_cast<double>((1u << static_cast<unsigned>(bit_depth)) - 1u);
}

cv::Mat saturationMask(const cv::Mat& frame, int bit_depth) {
  cv::Mat mask;
  cv::compare(frame, cv::Scalar(fullScale(bit_depth)), mask, cv::CMP_GE);
  return mask;
}

}  // namespace

cv::Mat eightBitPicture(const cv::Mat& frame, int bit_depth) {
  checkFrame(frame, bit_depth);
  if (frame.type() == CV_8UC1 && bit_depth == 8) return frame;
  cv::Mat out;
  frame.convertTo(out, CV_8U, 255.0 / fullScale(bit_depth));
  return out;
}

FrameMeasures measureFrame(const cv::Mat& frame, int bit_depth) {
  const cv::Mat picture = eightBitPicture(frame, bit_depth);
  FrameMeasures m;
  m.saturated = static_cast<double>(cv::countNonZero(saturationMask(frame, bit_depth))) /
                static_cast<double>(frame.total());
  // The central half in each direction: where a person puts what they focus
  // on, and away from the vignetted corners.
  const cv::Rect centre(picture.cols / 4, picture.rows / 4, std::max(1, picture.cols / 2),
                        std::max(1, picture.rows / 2));
  cv::Mat laplacian;
  cv::Laplacian(picture(centre), laplacian, CV_32F);
  cv::Scalar mean;
  cv::Scalar deviation;
  cv::meanStdDev(laplacian, mean, deviation);
  m.focus = deviation[0] * deviation[0];
  return m;
}

cv::Mat saturationOverlay(const cv::Mat& frame, int bit_depth) {
  cv::Mat bgr;
  cv::cvtColor(eightBitPicture(frame, bit_depth), bgr, cv::COLOR_GRAY2BGR);
  bgr.setTo(cv::Scalar(0, 0, 255), saturationMask(frame, bit_depth));
  return bgr;
}

LivePicture livePicture(const cv::Mat& frame, int bit_depth, bool saturation_overlay,
                        JpegEncoder& encoder) {
  LivePicture out;
  out.measures = measureFrame(frame, bit_depth);
  out.jpeg = encoder.encode(saturation_overlay ? saturationOverlay(frame, bit_depth)
                                               : eightBitPicture(frame, bit_depth));
  return out;
}

}  // namespace cylscan::firmware
