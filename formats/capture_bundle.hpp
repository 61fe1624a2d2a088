// SPDX-License-Identifier: Apache-2.0
// The capture bundle, format `cylscan-capture-1` (docs/formats.md, capture
// bundle).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "common/vocabulary.hpp"

namespace cylscan::formats {

struct FringeSetInfo {
  double period_deg = 0;          // θh or θl
  std::vector<double> stage_deg;  // executed stage angle of each frame
};

// The fringe sets a reader requires in "sets" and in each "camera_sets" entry.
// The contract is Both. OneOrBoth is an extension for a bundle recorded with a
// single pattern set: one of the two may be absent (never both), and the absent
// set's FringeSetInfo stays empty. Only `cylscan phase` reads with it, because
// only the wrapped phase can be had from one set; everything that needs the
// absolute phase keeps refusing such a bundle.
enum class SetsRequired { Both, OneOrBoth };

// A camera's own two sets (the extension field "camera_sets"): a ring scan's
// cameras see the same stage angles in different roles, so a camera whose
// sets differ from the top-level ones (main's) carries its own.
struct CameraSets {
  FringeSetInfo high;
  FringeSetInfo low;
  const FringeSetInfo& set(FringeSet id) const { return id == FringeSet::High ? high : low; }
  FringeSetInfo& set(FringeSet id) { return id == FringeSet::High ? high : low; }
};

struct CaptureInfo {
  std::vector<std::string> cameras;  // "main" first; "aux" for calibration bundles
  FringeSetInfo high;                // the top-level sets: main's
  FringeSetInfo low;
  // Extension (a reader that does not know it ignores it, like any unknown
  // field): the cameras whose sets are not the top-level ones, in capture.json as
  //   "camera_sets": {"cam90": {"high": {"period_deg", "stage_deg"}, "low": {...}}}.
  // Every key is a camera of `cameras` other than "main" (whose sets are the
  // top-level ones); each has both sets. Extras inside those
  // set objects stay in `extra` under "camera_sets" → camera → set.
  std::map<std::string, CameraSets, std::less<>> camera_sets;
  // Extension: the size of each camera's frames, in capture.json as
  //   "frame_sizes": {"main": [1000, 800], ...}   ([width, height]).
  // A reader that finds it refuses, before decoding anything, a frame whose
  // PNG header claims another size, so a corrupt or hostile header cannot
  // make it allocate more than the bundle declares. cylscan's writer always
  // writes it, from the frames it wrote (what is here on input is ignored).
  std::map<std::string, cv::Size, std::less<>> frame_sizes;
  // Unknown/extra fields, kept on write. Mirrors the layout of capture.json
  // without the known fields: top-level extras at the top, extras inside a set
  // object under "sets" → "high"/"low" (e.g. {"exposure_us": 800,
  // "sets": {"high": {"steps": [..]}}}). The writer merges the known fields over it.
  nlohmann::json extra = nlohmann::json::object();

  const FringeSetInfo& set(FringeSet id) const { return id == FringeSet::High ? high : low; }
  FringeSetInfo& set(FringeSet id) { return id == FringeSet::High ? high : low; }
  // A camera's own set: its "camera_sets" entry when it has one, else the top-level set.
  const FringeSetInfo& setOf(std::string_view camera, FringeSet id) const;
  // False only for the set a one-set bundle lacks (SetsRequired::OneOrBoth): a
  // set that is present has at least kMinFramesPerSet frames.
  bool hasSet(FringeSet id) const { return !set(id).stage_deg.empty(); }
  bool hasSetOf(std::string_view camera, FringeSet id) const {
    return !setOf(camera, id).stage_deg.empty();
  }
  bool hasOwnSets(std::string_view camera) const {
    return camera_sets.find(camera) != camera_sets.end();
  }
};

// Limits applied before any frame is decoded.
struct FrameLimits {
  int max_width = 16384;
  int max_height = 16384;
  std::int64_t max_pixels = 64LL * 1024 * 1024;
};

// Reads and validates a bundle. Every fault throws InputError naming the file.
// The constructor validates capture.json and every frame's PNG header (present,
// single-channel, 8/16-bit, within limits, one size per camera, no frame files
// beyond the angle list) without decoding any frame. `sets` says whether a set
// may be absent (SetsRequired); an absent set has no frames (frameCount 0), and
// a frame file in its directory is an error like any frame beyond the angle list.
class CaptureBundleReader {
 public:
  explicit CaptureBundleReader(std::filesystem::path dir, FrameLimits limits = {},
                               SetsRequired sets = SetsRequired::Both);

  const std::filesystem::path& dir() const { return dir_; }
  const CaptureInfo& info() const { return info_; }
  bool hasCamera(std::string_view camera) const;
  int frameCount(FringeSet set) const;  // of the top-level set (main's)
  // Of the camera's own set (info().setOf); InputError for an unknown camera.
  int frameCount(std::string_view camera, FringeSet set) const;
  // InputError (naming capture.json) for a camera the bundle does not have;
  // std::out_of_range for k outside [0, frameCount(camera, set)).
  std::filesystem::path framePath(std::string_view camera, FringeSet set, int k) const;
  // The size all frames of the camera share (checked when the bundle was opened).
  cv::Size frameSize(std::string_view camera) const;

  // Frame k of a set: CV_8UC1 or CV_16UC1. The PNG header is checked (single
  // channel, 8/16 bit, size within limits and equal to the camera's first
  // frame) before the image is decoded; a truncated or corrupt file is an error.
  cv::Mat readFrame(std::string_view camera, FringeSet set, int k) const;

 private:
  void requireCamera(std::string_view camera) const;  // InputError naming capture.json

  std::filesystem::path dir_;
  FrameLimits limits_;
  CaptureInfo info_;
  std::map<std::string, cv::Size, std::less<>> frame_sizes_;  // per camera
};

// Writes a bundle (always with both sets: the contract). Frames first; capture.json last
// (atomically), so a bundle without capture.json is never mistaken for a whole one.
//
// The constructor validates `info` (std::invalid_argument), creates the
// directory and removes a capture.json already there: the directory is being
// rewritten, and must not pass for a whole bundle while old and new frames mix.
// Every frame is written atomically. commit() requires every frame of every
// camera to have been written through this writer (std::logic_error otherwise),
// removes stale frame files of an earlier bundle (NN.png names the new angle
// lists do not have, which readers would reject), then writes capture.json.
class CaptureBundleWriter {
 public:
  CaptureBundleWriter(std::filesystem::path dir, CaptureInfo info);
  // CV_8UC1 or CV_16UC1, one size per camera (std::invalid_argument otherwise).
  void writeFrame(std::string_view camera, FringeSet set, int k, const cv::Mat& frame);
  void commit();  // writes capture.json

 private:
  struct CameraProgress {
    cv::Size size;                             // of the first frame written
    std::array<std::vector<bool>, 2> written;  // per set, per frame
  };

  std::filesystem::path dir_;
  CaptureInfo info_;
  std::map<std::string, CameraProgress, std::less<>> progress_;
};

// "NN" for frame k of a set of n frames: two digits, more when n >= 100 (as
// many as n has). std::invalid_argument unless 0 <= k < n. The file is "NN.png".
std::string frameFileName(int k, int n);

inline constexpr std::string_view kCaptureFormat = "cylscan-capture-1";
inline constexpr int kMinFramesPerSet = 3;

}  // namespace cylscan::formats
