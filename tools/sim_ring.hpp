// SPDX-License-Identifier: Apache-2.0
// The datasets of a 360° head (a ring board such as board/sim360), captured
// through tools/sim_capture.hpp along the firmware's ring plan:
//   --camera NAME  the one-direction dataset of camera NAME (tools/sim_dataset.hpp)
//                  on the head re-expressed in NAME's frame with a temporary aux,
//                  at the ring plan's angles of NAME's sets;
//   --turntable    the extrinsics dataset: the head on a turntable, a
//                  target of four spheres seen by every camera in turn;
//   neither        ring scans of the board's default scene (or --scene files).
#pragma once

#include "tools/sim_dataset.hpp"
#include "tools/sim_request.hpp"

namespace cylscan::tools {

void writeRingDataset(const SimulateRequest& request, SimClock::time_point started);

}  // namespace cylscan::tools
