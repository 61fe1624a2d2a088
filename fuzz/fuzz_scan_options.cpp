// SPDX-License-Identifier: Apache-2.0
// The JSON options of POST /api/v1/scans, as the HTTP layer hands them to the
// service: a body that is only white space means {}, anything else must
// parse as a JSON object (else 400 from the HTTP layer:
// json::parse_error, or json::out_of_range for a number such as 1e400), and the service
// then validates it (ServiceError 400 for bad options). The validation is
// reached through ScanService::scanEstimateBytes, which validates exactly as
// startScan does without starting a scan. Only ServiceError 400 may escape.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "fuzz/fuzz_support.hpp"
#include "fuzz/small_service.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using nlohmann::json;
  const std::string body(cylscan::fuzz::asText(data, size));
  json options = json::object();
  if (body.find_first_not_of(" \t\r\n") != std::string::npos) {
    try {
      options = json::parse(body);
    } catch (const json::exception&) {  // the HTTP layer's 400
      return 0;
    }
    if (!options.is_object()) return 0;
  }
  try {
    const std::uint64_t bytes = cylscan::fuzz::smallService().scanEstimateBytes(options);
    if (bytes == 0) throw std::logic_error("accepted options with an estimate of 0 bytes");
  } catch (const cylscan::firmware::ServiceError& e) {
    if (e.httpStatus() != 400) throw std::logic_error("bad options not answered 400");
  }
  return 0;
}
