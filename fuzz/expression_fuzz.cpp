// libFuzzer target: the expression parser and compiler (refdyn::Expression) on arbitrary text,
// then value, gradient and Hessian at a fixed point. refdyn::Error is the only expected
// outcome of a bad text; any other exception, a crash, a leak or undefined behaviour (ASan,
// UBSan) is a finding.
#include "refdyn/common/error.hpp"
#include "refdyn/expression/expression.hpp"

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const refdyn::Expression e(text, {"t", "x(E)", "q(j1)"}, {{"a", 1.5}}, 2);
    const double x[3] = {0.25, -0.75, 1.25};
    double value = 0.0, grad[3] = {0, 0, 0}, hess[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    e.evaluate(x, value, grad, hess);
    volatile double sink = value + grad[0] + grad[1] + grad[2] + hess[0] + hess[4] + hess[8];
    (void)sink;
    (void)e.value(x);
  } catch (const refdyn::Error&) {
    // a rejected text: expected
  }
  return 0;
}
