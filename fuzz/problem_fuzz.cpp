// libFuzzer target: a whole scenario built (io::parse_scenario, then build_problem: every number
// evaluated, every name bound, the model compiled, the initial state checked or projected, the
// partition chosen, the sweeps expanded). refdyn::Error is the only expected outcome of a bad
// scenario; any other exception, a crash, a leak, undefined behaviour or a timeout is a finding.
#include "refdyn/common/error.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/scenario/problem.hpp"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string yaml(reinterpret_cast<const char*>(data), size);
  try {
    const refdyn::ScenarioSpec spec = refdyn::io::parse_scenario(yaml, "fuzz.yaml");
    (void)refdyn::build_problem(spec);
  } catch (const refdyn::Error&) {
    // a rejected scenario: expected
  }
  return 0;
}
