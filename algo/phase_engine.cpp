// SPDX-License-Identifier: Apache-2.0
#include "algo/phase_engine.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <utility>

#include "algo/order_residual.hpp"
#include "algo/phase_pipeline.hpp"

namespace cylscan::algo {
namespace {

cv::Size checkedSize(cv::Size size) {
  if (size.width <= 0 || size.height <= 0) {
    throw std::invalid_argument("PhaseEngine: image size " + std::to_string(size.width) + "x" +
                                std::to_string(size.height) + " is empty");
  }
  return size;
}

std::string where(FringeSet set, int k) {
  return "fold(" + std::string(toString(set)) + ", k=" + std::to_string(k) + "): ";
}

}  // namespace

PhaseOptions resolvePhaseOptions(PhaseOptions o) {
  if (o.bit_depth < 8 || o.bit_depth > 16) {
    throw std::invalid_argument("PhaseOptions::bit_depth is " + std::to_string(o.bit_depth) +
                                "; it must be 8..16");
  }
  const int max_pixel = (1 << o.bit_depth) - 1;
  if (o.saturation_level == -1) o.saturation_level = max_pixel;
  if (o.saturation_level < 1 || o.saturation_level > max_pixel) {
    throw std::invalid_argument("PhaseOptions::saturation_level is " +
                                std::to_string(o.saturation_level) + "; it must be -1 or 1.." +
                                std::to_string(max_pixel) + " for " + std::to_string(o.bit_depth) +
                                "-bit frames");
  }
  if (o.min_modulation == -1) o.min_modulation = 0.02 * max_pixel;
  if (!std::isfinite(o.min_modulation) || o.min_modulation < 0) {
    std::ostringstream msg;
    msg << "PhaseOptions::min_modulation is " << o.min_modulation << "; it must be -1 or >= 0";
    throw std::invalid_argument(msg.str());
  }
  if (o.max_order_error_rad != -1 &&
      !(o.max_order_error_rad > 0 && o.max_order_error_rad <= std::numbers::pi)) {
    std::ostringstream msg;
    msg << "PhaseOptions::max_order_error_rad is " << o.max_order_error_rad
        << "; it must be -1 or in (0, π]";
    throw std::invalid_argument(msg.str());
  }
  return o;
}

void checkFoldFrame(FringeSet set, int k, const cv::Mat& frame, cv::Size size, int bit_depth) {
  if (frame.empty()) throw std::invalid_argument(where(set, k) + "the frame is empty");
  if (frame.type() != CV_8UC1 && frame.type() != CV_16UC1) {
    throw std::invalid_argument(where(set, k) + "the frame is " + cv::typeToString(frame.type()) +
                                "; expected single-channel CV_8UC1 or CV_16UC1");
  }
  if (frame.size() != size) {
    throw std::invalid_argument(where(set, k) + "the frame is " + std::to_string(frame.cols) + "x" +
                                std::to_string(frame.rows) + "; the engine expects " +
                                std::to_string(size.width) + "x" + std::to_string(size.height));
  }
  if (frame.type() == CV_8UC1 && bit_depth != 8) {
    throw std::invalid_argument(where(set, k) +
                                "the frame is 8-bit but PhaseOptions::bit_depth is " +
                                std::to_string(bit_depth));
  }
  if (frame.type() == CV_16UC1 && bit_depth == 8) {
    throw std::invalid_argument(where(set, k) +
                                "the frame is 16-bit but PhaseOptions::bit_depth is 8");
  }
}

double modulationCodesPerCount(int max_pixel) {
  return 32768.0 / (max_pixel + 1);
}

std::uint32_t minModulationCode(const PhaseOptions& resolved) {
  const int max_pixel = (1 << resolved.bit_depth) - 1;
  return static_cast<std::uint32_t>(
      std::min(65535.0, std::ceil(resolved.min_modulation * modulationCodesPerCount(max_pixel))));
}

PipelineSetup::PipelineSetup(cv::Size size_, const PhaseOptions& options_,
                             const FringeSetGeometry& high_, const FringeSetGeometry& low_)
    : size(checkedSize(size_)),
      options(resolvePhaseOptions(options_)),
      high(high_, "high"),
      low(low_, "low"),
      unwrapper(high_.period_deg, low_.period_deg),
      fusion(unwrapper.periodHighDeg(), unwrapper.periodLowDeg(), high.noiseGain(), low.noiseGain(),
             unwrapper.ratioHigh()) {}

ResidualRule residualRule(std::span<std::int32_t> residuals, const PipelineSetup& setup) {
  const TwoWavelengthUnwrapper& u = setup.unwrapper;
  const int bits = 16 + u.fixedParams().shift;
  const ResidualStatistics stats = measureResiduals(residuals, bits);
  ResidualRule rule;
  rule.centre = stats.centre;
  if (const std::optional<double>& reference = setup.options.order_reference_rad) {
    const std::int32_t unit = std::int32_t{1} << bits;
    const auto anchor = wrapResidual(
        std::llround(*reference / (2 * std::numbers::pi) * static_cast<double>(unit)), bits);
    // Too few samples: no centre was measured, and the calibration's is the best guess.
    rule.centre = stats.samples >= kMinResidualSamples
                      ? anchor + wrapResidual(std::int64_t{stats.centre} - anchor, bits)
                      : anchor;
  }
  if (setup.options.max_order_error_rad != -1) {
    rule.bound = u.fixedResidualBound(setup.options.max_order_error_rad);
  } else if (stats.samples >= kMinResidualSamples) {
    rule.bound = residualBound(stats, bits);
  } else {
    rule.bound = u.fixedResidualBound(std::numbers::pi / 2);
  }
  rule.report.samples = stats.samples >= kMinResidualSamples ? stats.samples : 0;
  rule.report.centre_rad = u.fixedResidualToRadians(rule.centre);
  rule.report.spread_rad = u.fixedResidualToRadians(stats.spread);
  rule.report.bound_rad = u.fixedResidualToRadians(rule.bound);
  return rule;
}

std::size_t residualSampleStride(cv::Size size) {
  const auto pixels = static_cast<std::size_t>(size.area());
  std::size_t stride = std::max<std::size_t>(1, pixels / 8192) | 1u;
  if (stride > 1 && static_cast<std::size_t>(size.width) % stride == 0) stride += 2;
  return stride;
}

// Bits the kernels use for the flags.
static_assert(kLowModulation == 1 && kSaturated == 2 && kOrderInconsistent == 4);

struct PhaseEngine::Impl {
  Impl(cv::Size size, const FringeSetGeometry& high, const FringeSetGeometry& low,
       const PhaseOptions& options)
      : setup(size, options, high, low),
        pipeline(setup.options.fixed_point ? makeFixedPipeline(setup)
                                           : makeReferencePipeline(setup)) {
    reset();
  }

  void reset() {
    for (int i = 0; i < 2; ++i) {
      const std::size_t n = setup.weights(i == 0 ? FringeSet::High : FringeSet::Low).frameCount();
      folded[i].assign(n, false);
      count[i] = 0;
    }
    active.reset();
    pipeline->reset();
  }

  bool complete(FringeSet set) const {
    return count[fringeSetIndex(set)] == static_cast<int>(folded[fringeSetIndex(set)].size());
  }

  PipelineSetup setup;
  std::unique_ptr<PhasePipeline> pipeline;
  std::vector<bool> folded[2];
  int count[2] = {0, 0};
  std::optional<FringeSet> active;  // started and not complete
};

// The by-value geometry is the public signature.
// NOLINTNEXTLINE(performance-unnecessary-value-param)
PhaseEngine::PhaseEngine(cv::Size size, FringeSetGeometry high, FringeSetGeometry low,
                         PhaseOptions options)
    : impl_(std::make_unique<Impl>(size, high, low, options)) {}

PhaseEngine::~PhaseEngine() = default;
PhaseEngine::PhaseEngine(PhaseEngine&&) noexcept = default;
PhaseEngine& PhaseEngine::operator=(PhaseEngine&&) noexcept = default;

void PhaseEngine::fold(FringeSet set, int k, const cv::Mat& frame) {
  Impl& im = *impl_;
  const int n = static_cast<int>(im.folded[fringeSetIndex(set)].size());
  if (k < 0 || k >= n) {
    throw std::out_of_range(where(set, k) + "the " + std::string(toString(set)) + " set has " +
                            std::to_string(n) + " frames (k = 0.." + std::to_string(n - 1) + ")");
  }
  checkFoldFrame(set, k, frame, im.setup.size, im.setup.options.bit_depth);
  if (im.folded[fringeSetIndex(set)][static_cast<std::size_t>(k)]) {
    throw std::logic_error(where(set, k) + "frame " + std::to_string(k) + " of the " +
                           std::string(toString(set)) + " set was already folded");
  }
  if (im.active && *im.active != set) {
    const FringeSet a = *im.active;
    throw std::logic_error(where(set, k) + "the " + std::string(toString(a)) + " set has " +
                           std::to_string(im.count[fringeSetIndex(a)]) + " of " +
                           std::to_string(im.folded[fringeSetIndex(a)].size()) +
                           " frames folded; fold all frames of one set before the other");
  }
  if (!im.active) {
    im.pipeline->beginSet(set);
    im.active = set;
  }
  const bool completes_set = im.count[fringeSetIndex(set)] + 1 == n;
  im.pipeline->fold(set, k, frame, completes_set);
  im.folded[fringeSetIndex(set)][static_cast<std::size_t>(k)] = true;
  ++im.count[fringeSetIndex(set)];
  if (im.complete(set)) im.active.reset();
}

void PhaseEngine::setOrderReference(std::optional<double> reference_rad) {
  if (reference_rad && !std::isfinite(*reference_rad))
    throw std::invalid_argument("order reference: not a finite angle");
  impl_->setup.options.order_reference_rad = reference_rad;
}

PhaseMaps PhaseEngine::finalize() {
  PhaseMaps maps;
  finalize(maps);
  return maps;
}

void PhaseEngine::finalize(PhaseMaps& maps) {
  const Impl& im = *impl_;
  if (!im.complete(FringeSet::High) || !im.complete(FringeSet::Low)) {
    throw std::logic_error("finalize(): frames are missing: high " + std::to_string(im.count[0]) +
                           " of " + std::to_string(im.folded[0].size()) + ", low " +
                           std::to_string(im.count[1]) + " of " +
                           std::to_string(im.folded[1].size()) + " folded");
  }
  im.pipeline->finalize(maps);
}

void PhaseEngine::finalizeCompact(CompactPhase& out) {
  const Impl& im = *impl_;
  if (!im.setup.options.fixed_point) {
    throw std::logic_error("finalizeCompact(): only the fixed-point path has a compact form");
  }
  if (!im.complete(FringeSet::High) || !im.complete(FringeSet::Low)) {
    throw std::logic_error(
        "finalizeCompact(): frames are missing: high " + std::to_string(im.count[0]) + " of " +
        std::to_string(im.folded[0].size()) + ", low " + std::to_string(im.count[1]) + " of " +
        std::to_string(im.folded[1].size()) + " folded");
  }
  im.pipeline->finalizeCompact(out);
}

void PhaseEngine::reset() {
  impl_->reset();
}

std::size_t PhaseEngine::workingStateBytes() const {
  return impl_->pipeline->workingStateBytes();
}
cv::Size PhaseEngine::size() const {
  return impl_->setup.size;
}
int PhaseEngine::frameCount(FringeSet set) const {
  return static_cast<int>(impl_->setup.weights(set).frameCount());
}
double PhaseEngine::conditionNumber(FringeSet set) const {
  return impl_->setup.weights(set).conditionNumber();
}
double PhaseEngine::noiseGain(FringeSet set) const {
  return impl_->setup.weights(set).noiseGain();
}
const PhaseOptions& PhaseEngine::options() const {
  return impl_->setup.options;
}

namespace {
// Keeps a map's memory when it already has the size and type, so a scan loop
// that finalizes into the same maps allocates nothing.
void reuseOrCreate(cv::Mat& m, cv::Size size, int type) {
  if (!m.isContinuous() || m.size() != size || m.type() != type) m.release();
  m.create(size, type);
}
}  // namespace

void preparePhaseMaps(PhaseMaps& maps, cv::Size size) {
  const auto prepare = [&](cv::Mat& m, int type) { reuseOrCreate(m, size, type); };
  prepare(maps.wrapped_high, CV_32FC1);
  prepare(maps.wrapped_low, CV_32FC1);
  prepare(maps.modulation_high, CV_32FC1);
  prepare(maps.modulation_low, CV_32FC1);
  prepare(maps.texture, CV_32FC1);
  prepare(maps.fringe_order, CV_16SC1);
  prepare(maps.absolute, CV_32FC1);
  prepare(maps.fused, CV_32FC1);
  prepare(maps.invalid, CV_8UC1);
  maps.valid_fraction = 0;
}

void prepareCompactPhase(CompactPhase& out, cv::Size size) {
  const auto prepare = [&](cv::Mat& m, int type) { reuseOrCreate(m, size, type); };
  prepare(out.absolute, CV_32SC1);
  prepare(out.fused, CV_32FC1);
  prepare(out.invalid, CV_8UC1);
  prepare(out.texture, CV_16UC1);
}

}  // namespace cylscan::algo
