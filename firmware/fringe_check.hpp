// SPDX-License-Identifier: Apache-2.0
// The fringe check of the set-up page: what a short scan's phase maps say
// about a camera's exposure for scanning. The phase noise of a pixel is
// σI·sqrt(2/N)/B (B the fringes' modulation), so the brighter the fringes
// the better, up to the camera's full scale: a crest that clips bends the
// sinusoid and biases the phase by more than any noise. The check says
// which way to move the exposure, and shows where the fringes are usable.
#pragma once

#include <string_view>

#include <opencv2/core.hpp>

#include "algo/phase_engine.hpp"

namespace cylscan::firmware {

enum class ExposureAdvice { kRight, kRaise, kLower };
std::string_view toString(ExposureAdvice advice);  // "right", "raise", "lower"

struct FringeQuality {
  // The median modulation B of the high set over the pixels that the
  // fringes reach (B at least the engine's least modulation), in counts.
  double modulation_median = 0;
  double lit = 0;        // the share of pixels the fringes reach
  double usable = 0;     // the share of pixels whose phase a scan would keep
  double saturated = 0;  // the share saturated in a frame of either set
  // The brightest fringe crests, A + B at the 99.5th percentile of the lit
  // pixels, as a share of full scale.
  double peak = 0;
  ExposureAdvice advice = ExposureAdvice::kRight;
  // CV_8UC3 (BGR): B on a grey scale (white = half of full scale, the most a
  // sinusoid within range can have), saturated pixels red.
  cv::Mat picture;
};

// Lower when more than this share of the lit pixels saturate: a few
// specular glints are tolerable, a clipped surface is not.
inline constexpr double kMaxSaturatedShare = 0.001;
// Raise when the brightest crests use less than this share of full scale:
// doubling the exposure would halve the phase noise and clip nothing.
inline constexpr double kMinPeakShare = 0.45;

// The check of one camera's maps (any number of frames per set). `options`
// are the engine's, resolved (PhaseEngine::options()); std::invalid_argument
// for maps of mismatched sizes or types.
FringeQuality measureFringes(const algo::PhaseMaps& maps, const algo::PhaseOptions& options);

}  // namespace cylscan::firmware
