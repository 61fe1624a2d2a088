// SPDX-License-Identifier: Apache-2.0
// A build without the virtual head (CYLSCAN_WITH_SIM=OFF): the profile parser
// refuses sim boards (drivers/board_profile.cpp), and a profile that reaches
// Board::open with [sim] set all the same is refused here.
#include <stdexcept>
#include <string>

#include "drivers/board.hpp"

namespace cylscan::drivers {

bool virtualHeadBuilt() {
  return false;
}

// No head is ever made, so there is none to delete.
void Board::HeadDeleter::operator()(sim::VirtualHead* /*head*/) const {}

void Board::openSim(const std::optional<std::filesystem::path>& /*scene*/) {
  throw std::invalid_argument("board '" + profile_.name + "' (" + profile_.file.string() +
                              "): [sim]: " + std::string(kNoVirtualHead));
}

}  // namespace cylscan::drivers
