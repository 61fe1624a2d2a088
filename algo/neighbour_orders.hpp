// SPDX-License-Identifier: Apache-2.0
// Fringe orders of ambiguous pixels decided by their confident neighbours.
//
// A pixel whose order residual lies beyond the scan's bound is nearly as close
// to the next order as to its own: its own phases cannot tell which is right.
// On a continuous surface its neighbours can. Where at least kMinConfident of
// its 8 neighbours have trusted orders and their Φ agree within a quarter
// fringe (π/2), the surface is smooth there, and the pixel takes whichever of
// its two candidate orders (its rounded order, and the next one on the side
// its residual points to) puts its Φ within a quarter fringe of their mean.
// Elsewhere it stays invalid:
// - at a depth edge or a shadow border its neighbours' Φ disagree, or too few
//   of them are trusted;
// - when neither candidate lands near the neighbours, the pixel's own phase
//   is wrong (a reflection, a mixed pixel), and no order makes it right.
// Both candidates are 2π apart, so at most one of them can be within π/2 of
// the mean. Only neighbours trusted by their own residual count: a decided
// pixel never decides another, so no error spreads across the image.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

namespace cylscan::algo {

inline constexpr int kMinConfidentNeighbours = 5;

// Calls decide(i, mean) for each pixel i whose invalid reasons are exactly
// `ambiguous` and whose trusted neighbours (invalid == 0) agree, with the mean
// of their absolute_of(j); decide returns whether it set the pixel's order.
// Those pixels become valid (invalid = 0). Value is the type of Φ: an integer
// type in binary-angle units for the fixed-point path (then mean is the
// truncated integer mean, the same bits on every CPU), double radians for the
// reference. `agree` is the largest spread (max − min) of the neighbours' Φ
// that counts as agreeing. Returns the number of pixels decided.
template <typename Value, typename AbsoluteOf, typename Decide>
std::size_t decideOrdersFromNeighbours(cv::Size size, std::uint8_t* invalid, std::uint8_t ambiguous,
                                       Value agree, AbsoluteOf&& absolute_of, Decide&& decide) {
  const int w = size.width;
  const int h = size.height;
  const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  std::vector<std::pair<std::size_t, Value>> candidates;
  // Ambiguous pixels are few: memchr skips the others many bytes at a time,
  // which keeps this pass a small part of finalize.
  for (std::size_t i = 0; i < n; ++i) {
    const void* hit = std::memchr(invalid + i, ambiguous, n - i);
    if (hit == nullptr) break;
    i = static_cast<std::size_t>(static_cast<const std::uint8_t*>(hit) - invalid);
    const int y = static_cast<int>(i / static_cast<std::size_t>(w));
    const int x = static_cast<int>(i % static_cast<std::size_t>(w));
    int count = 0;
    Value lo = std::numeric_limits<Value>::max();
    Value hi = std::numeric_limits<Value>::lowest();
    Value sum = 0;
    for (int dy = -1; dy <= 1; ++dy) {
      const int ny = y + dy;
      if (ny < 0 || ny >= h) continue;
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = x + dx;
        if ((dx == 0 && dy == 0) || nx < 0 || nx >= w) continue;
        const std::size_t j = static_cast<std::size_t>(ny) * static_cast<std::size_t>(w) +
                              static_cast<std::size_t>(nx);
        if (invalid[j] != 0) continue;
        const Value v = absolute_of(j);
        lo = std::min(lo, v);
        hi = std::max(hi, v);
        sum += v;
        ++count;
      }
    }
    if (count < kMinConfidentNeighbours || hi - lo > agree) continue;
    candidates.emplace_back(i, sum / static_cast<Value>(count));
  }
  // Decided only now, so that a pixel decided here never counts as another's
  // trusted neighbour.
  std::size_t decided = 0;
  for (const auto& [i, mean] : candidates) {
    if (!decide(i, mean)) continue;
    invalid[i] = 0;
    ++decided;
  }
  return decided;
}

}  // namespace cylscan::algo
