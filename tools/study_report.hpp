// SPDX-License-Identifier: Apache-2.0
// report.md of `cylscan study`: the paper's tables with its published figures
// beside the virtual head's measurements, the truth comparisons, the
// acceptance checks and the dataset parameters.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace cylscan::tools {

// `results`: the study's results.json (see tools/study.cpp).
std::string studyReport(const nlohmann::json& results);

}  // namespace cylscan::tools
