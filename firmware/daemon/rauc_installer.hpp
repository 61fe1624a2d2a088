// SPDX-License-Identifier: Apache-2.0
// UpdateInstaller on RAUC 1.8 (service de.pengutronix.rauc, object /,
// interface de.pengutronix.rauc.Installer) through sd-bus: RAUC's only API
// is D-Bus, and sd-bus is systemd's own library, already on every image.
// Every call opens its own system-bus connection (an sd_bus is not shared
// between threads), so an install's wait never holds one an HTTP thread uses.
// A build without libsystemd gets an installer that is always Unavailable.
#pragma once

#include <memory>

#include "firmware/daemon/update_installer.hpp"

namespace cylscan::firmware {

std::unique_ptr<UpdateInstaller> makeRaucInstaller();

}  // namespace cylscan::firmware
