// SPDX-License-Identifier: Apache-2.0
// The stereo calibration file (OpenCV FileStorage YAML) through
// readStereoCalibration, written to a .yaml file per input. Every fault must
// be an InputError; an accepted calibration must pass its own rules again
// when written and read back.
#include <cstddef>
#include <cstdint>
#include <stdexcept>

#include "formats/input_error.hpp"
#include "formats/stereo_calibration.hpp"
#include "fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace formats = cylscan::formats;
  const auto file = cylscan::fuzz::scratchDir() / "stereo.yaml";
  cylscan::fuzz::writeFile(file, cylscan::fuzz::asText(data, size));
  try {
    const formats::StereoCalibration calib = formats::readStereoCalibration(file);
    const auto again_file = cylscan::fuzz::scratchDir() / "again.yaml";
    formats::writeStereoCalibration(again_file, calib);
    const formats::StereoCalibration again = formats::readStereoCalibration(again_file);
    if (again.image_width != calib.image_width || again.image_height != calib.image_height ||
        again.R != calib.R || again.T != calib.T)
      throw std::logic_error("a calibration does not survive write/read");
  } catch (const formats::InputError&) {
  }
  return 0;
}
