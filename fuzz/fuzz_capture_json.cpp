// SPDX-License-Identifier: Apache-2.0
// capture.json through CaptureBundleReader: the input is written as the
// capture.json of a bundle folder that holds valid frames (6 per set, 8×6
// 8-bit PNG, for the cameras "main" and "aux"), so a capture.json that
// passes goes on to the frame checks and a frame is read. Every fault must
// be an InputError; a bundle that opens must name only frames inside it.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>

#include <opencv2/core.hpp>

#include "formats/capture_bundle.hpp"
#include "formats/images.hpp"
#include "formats/input_error.hpp"
#include "fuzz/fuzz_support.hpp"

namespace {

namespace fs = std::filesystem;
namespace formats = cylscan::formats;

const fs::path& bundleDir() {
  static const fs::path dir = [] {
    const fs::path d = cylscan::fuzz::scratchDir() / "bundle";
    const cv::Mat frame(6, 8, CV_8UC1, cv::Scalar(100));
    for (const char* camera : {"main", "aux"})
      for (const char* set : {"high", "low"}) {
        fs::create_directories(d / camera / set);
        for (int k = 0; k < 6; ++k)
          formats::writePng(d / camera / set / (formats::frameFileName(k, 6) + ".png"), frame);
      }
    return d;
  }();
  return dir;
}

void require(bool ok, const char* what) {
  if (!ok) throw std::logic_error(what);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const fs::path& dir = bundleDir();
  cylscan::fuzz::writeFile(dir / "capture.json", cylscan::fuzz::asText(data, size));
  try {
    const formats::CaptureBundleReader reader(dir);
    const formats::CaptureInfo& info = reader.info();
    require(!info.cameras.empty() && reader.hasCamera("main"), "opened without camera main");
    for (const cylscan::FringeSet set : cylscan::kFringeSets) {
      const int n = reader.frameCount(set);
      require(n >= formats::kMinFramesPerSet && n <= 6, "opened with a frame count outside 3..6");
      for (const std::string& camera : info.cameras) {
        const fs::path frame = reader.framePath(camera, set, n - 1);
        require(frame.parent_path().parent_path().parent_path() == dir,
                "a frame path outside the bundle");
      }
    }
    const cv::Mat frame = reader.readFrame("main", cylscan::FringeSet::Low, 0);
    require(frame.rows == 6 && frame.cols == 8, "read a frame of another size");
  } catch (const formats::InputError&) {
  }
  return 0;
}
