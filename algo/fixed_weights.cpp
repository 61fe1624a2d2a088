// SPDX-License-Identifier: Apache-2.0
#include "algo/fixed_weights.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace cylscan::algo {
namespace {

double sumAbs(std::span<const FrameWeights> frames, double FrameWeights::*member) {
  double total = 0;
  for (const FrameWeights& f : frames)
    total += std::abs(f.*member);
  return total;
}

std::vector<std::int32_t> quantizeMember(const ShiftWeights& weights, double FrameWeights::*member,
                                         double scale, std::int64_t target, int max_pixel) {
  std::vector<double> scaled;
  for (const FrameWeights& f : weights.frames())
    scaled.push_back(f.*member * scale);
  const std::vector<std::int64_t> rounded = roundToSum(scaled, target);
  std::int64_t abs_sum = 0;
  for (std::int64_t q : rounded)
    abs_sum += q < 0 ? -q : q;
  if (abs_sum * max_pixel > FixedSetWeights::kSumLimit) {
    throw std::logic_error("fixed-point weights of the " + weights.setName() +
                           " set exceed the int32 accumulator bound");
  }
  return std::vector<std::int32_t>(rounded.begin(), rounded.end());
}

}  // namespace

std::vector<std::int64_t> roundToSum(std::span<const double> values, std::int64_t target) {
  std::vector<std::int64_t> out(values.size());
  std::int64_t total = 0;
  for (std::size_t k = 0; k < values.size(); ++k) {
    out[k] = std::llround(values[k]);
    total += out[k];
  }
  std::int64_t deficit = target - total;
  if (deficit == 0 || values.empty()) return out;
  // Visit entries by how much they gain from moving one step toward the target.
  std::vector<std::size_t> order(values.size());
  std::iota(order.begin(), order.end(), 0);
  const double direction = deficit > 0 ? 1.0 : -1.0;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) {
    return direction * (values[i] - static_cast<double>(out[i])) >
           direction * (values[j] - static_cast<double>(out[j]));
  });
  const std::int64_t step = deficit > 0 ? 1 : -1;
  for (std::size_t n = 0; deficit != 0; ++n) {
    out[order[n % order.size()]] += step;
    deficit -= step;
  }
  return out;
}

std::int64_t FixedSetWeights::sharedTextureScale(std::span<const ShiftWeights* const> sets,
                                                 int max_pixel) {
  double abs_total = 0;
  std::int64_t frames = 0;
  for (const ShiftWeights* w : sets) {
    abs_total += sumAbs(w->frames(), &FrameWeights::a);
    frames += static_cast<std::int64_t>(w->frameCount());
  }
  // Each even weight may round by up to 2 away from a_scale·|w|, plus one for the flag.
  const double room = static_cast<double>(kSumLimit - 1) / max_pixel - 2.0 * frames;
  const auto scale = static_cast<std::int64_t>(std::floor(room / abs_total / 2)) * 2;
  if (scale < 2) throw std::logic_error("no room for the texture weights in int32");
  return scale;
}

FixedSetWeights FixedSetWeights::quantize(const ShiftWeights& weights, int max_pixel,
                                          std::int64_t a_scale) {
  FixedSetWeights out;
  const double worst = std::max(sumAbs(weights.frames(), &FrameWeights::c),
                                sumAbs(weights.frames(), &FrameWeights::s));
  const double frames = static_cast<double>(weights.frameCount());
  // Rounding (<= 1/2 each) and the sum correction (<= 1 each) add at most N + N/2.
  out.cs_scale = std::floor((static_cast<double>(kSumLimit) / max_pixel - 2 * frames) / worst);
  out.c = quantizeMember(weights, &FrameWeights::c, out.cs_scale, 0, max_pixel);
  out.s = quantizeMember(weights, &FrameWeights::s, out.cs_scale, 0, max_pixel);
  // Texture: even weights (q = 2·h) so that the LSB of the sum is free for the flag.
  std::vector<double> halves;
  for (const FrameWeights& f : weights.frames())
    halves.push_back(f.a * static_cast<double>(a_scale) / 2);
  const std::vector<std::int64_t> rounded = roundToSum(halves, a_scale / 2);
  out.a.reserve(rounded.size());
  for (std::int64_t h : rounded)
    out.a.push_back(static_cast<std::int32_t>(2 * h));
  out.a_scale = a_scale;
  return out;
}

}  // namespace cylscan::algo
