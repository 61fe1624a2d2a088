// SPDX-License-Identifier: Apache-2.0
#include "firmware/stereo_geometry.hpp"

#include <string>

#include "formats/input_error.hpp"
#include "formats/size_text.hpp"

namespace cylscan::firmware {
namespace {

cv::Size imageSize(const formats::StereoCalibration& calib) {
  return {calib.image_width, calib.image_height};
}

}  // namespace

algo::PinholeCamera mainCamera(const formats::StereoCalibration& calib) {
  return {calib.camera_matrix_main, calib.dist_coeffs_main, imageSize(calib)};
}

algo::PinholeCamera auxCamera(const formats::StereoCalibration& calib) {
  return {calib.camera_matrix_aux, calib.dist_coeffs_aux, imageSize(calib)};
}

algo::StereoGeometry toStereoGeometry(const formats::StereoCalibration& calib) {
  return {mainCamera(calib), auxCamera(calib), calib.R, calib.T};
}

formats::StereoCalibration toStereoCalibration(const algo::StereoGeometry& geometry) {
  formats::StereoCalibration calib;
  calib.image_width = geometry.main.image_size.width;
  calib.image_height = geometry.main.image_size.height;
  calib.camera_matrix_main = geometry.main.camera_matrix;
  calib.dist_coeffs_main = geometry.main.dist_coeffs;
  calib.camera_matrix_aux = geometry.aux.camera_matrix;
  calib.dist_coeffs_aux = geometry.aux.dist_coeffs;
  calib.R = geometry.rotation;
  calib.T = geometry.translation;
  return calib;
}

void requireStereoImageSize(const std::filesystem::path& stereo_file,
                            const formats::StereoCalibration& calib, cv::Size size,
                            const std::filesystem::path& images) {
  if (imageSize(calib) == size) return;
  throw formats::InputError(stereo_file, "calibrated for " + formats::sizeText(imageSize(calib)) +
                                             " images, but " + images.string() + " has " +
                                             formats::sizeText(size) + " images");
}

}  // namespace cylscan::firmware
