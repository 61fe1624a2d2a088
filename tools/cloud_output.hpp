// SPDX-License-Identifier: Apache-2.0
// Shared by reconstruct and scan: the quasi-calibration file, and the point
// cloud and depth map of an xyz map. One implementation with the daemon's:
// firmware/reconstruction.hpp.
#pragma once

#include "firmware/reconstruction.hpp"

namespace cylscan::tools {

using firmware::cloudOfMaps;
using firmware::depthOfMap;
using firmware::readQuasiCalibration;

}  // namespace cylscan::tools
