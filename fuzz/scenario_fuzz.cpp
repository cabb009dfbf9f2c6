// libFuzzer target: the scenario parser (refdyn::io::parse_scenario) on arbitrary YAML text.
// refdyn::Error is the only expected outcome of a bad scenario; any other exception, a crash,
// a leak or undefined behaviour (ASan, UBSan) is a finding.
#include "refdyn/common/error.hpp"
#include "refdyn/io/scenario.hpp"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string yaml(reinterpret_cast<const char*>(data), size);
  try {
    (void)refdyn::io::parse_scenario(yaml, "fuzz.yaml");
  } catch (const refdyn::Error&) {
    // a rejected scenario: expected
  }
  return 0;
}
