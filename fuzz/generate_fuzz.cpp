// libFuzzer target: `refdyn generate` on random models. The input's bytes choose a chain of 1–4
// joints (revolute or prismatic, axes, joint origins with URDF-style rounded angles such as
// 1.57079632679 and 3.14159265359, masses, centres of mass, inertias), a point on its last link
// and at most one task row; the scenario is built and its reference dynamics generated as C
// (generate_symbolic, c_source: the tape that records the composite-rigid-body M and
// Newton–Euler c + g, where a use after free once crashed the command on a 7-DOF arm).
// refdyn::Error is the only expected outcome; a crash, another exception, a leak, undefined
// behaviour or a timeout is a finding.
#include "refdyn/common/error.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/symbolic/symbolic.hpp"

#include <cstddef>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>

namespace {

/// Reads the input a byte at a time (zeros past its end).
struct Bytes {
  const std::uint8_t* data;
  std::size_t size, at = 0;
  unsigned next() { return at < size ? data[at++] : 0u; }
  /// One of `count` choices.
  unsigned pick(unsigned count) { return next() % count; }
  /// A number in [lo, hi] on a grid of 256 values.
  double in(double lo, double hi) { return lo + (hi - lo) * next() / 255.0; }
};

std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.12g", v);
  return b;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Bytes in{data, size};
  static const char* angles[] = {"0", "1.57079632679", "-1.57079632679", "3.14159265359", "0.5236", "pi/2"};
  static const char* axes[] = {"[0, 0, 1]", "[0, 1, 0]", "[1, 0, 0]", "[1, 1, 0]", "[0, 0, -1]"};
  const int n = 1 + static_cast<int>(in.pick(4));
  std::string links, q, qd, q1;
  for (int i = 0; i < n; ++i) {
    const std::string name = "l" + std::to_string(i + 1), joint = "j" + std::to_string(i + 1);
    const bool prismatic = in.pick(4) == 0;
    links += "    - {name: " + name + ", joint: " + joint + ", parent: " + (i ? "l" + std::to_string(i) : "base") +
             ", type: " + (prismatic ? "prismatic" : "revolute") + ", axis: " + axes[in.pick(5)] +
             ", origin: {xyz: [" + num(in.in(-0.5, 0.5)) + ", " + num(in.in(-0.5, 0.5)) + ", " + num(in.in(-0.5, 0.5)) +
             "], rpy: [" + angles[in.pick(6)] + ", " + angles[in.pick(6)] + ", " + angles[in.pick(6)] + "]}, mass: " +
             num(in.in(0.1, 5)) + ", com: [" + num(in.in(-0.2, 0.2)) + ", " + num(in.in(-0.2, 0.2)) + ", " +
             num(in.in(-0.2, 0.2)) + "], inertia: [";
    // principal moments that a body can have (each at most the sum of the two others)
    const double a = in.in(0.001, 0.1), b = in.in(0.001, 0.1), c = in.in(std::abs(a - b) + 1e-4, a + b);
    links += num(a) + ", " + num(b) + ", " + num(c) + "]}\n";
    const std::string qi = num(in.in(-1, 1));
    if (i == 0) q1 = qi;
    q += std::string(i ? ", " : "") + joint + ": " + qi;
    qd += std::string(i ? ", " : "") + joint + ": 0";
  }
  std::string constraints = "constraints: []\n";
  switch (in.pick(3)) {
    case 0: constraints = "constraints:\n  - {name: height, kind: point_coordinate, point: E, axis: z, function: 0.1*t}\n"; break;
    case 1:
      constraints = "constraints:\n  - {name: turn, kind: joint_trajectory, joint: j1, function: " + q1 + " + 0.2*sin(t)}\n";
      break;
    default: break;
  }
  const std::string yaml = "name: fuzz_chain\nmodel:\n  gravity: [0, 0, -9.81]\n  links:\n" + links +
                           "  points:\n    E: {link: l" + std::to_string(n) + ", position: [" + num(in.in(-0.3, 0.3)) +
                           ", 0, 0.1]}\n" + constraints + "initial:\n  q: {" + q + "}\n  qd: {" + qd +
                           "}\n  consistency: project\nintegrator: {method: rk4, step: 1e-3, t0: 0, t1: 0.01}\n";
  try {
    const auto problem = refdyn::build_problem(refdyn::io::parse_scenario(yaml, "fuzz.yaml"));
    const refdyn::SymbolicReferenceDynamics s = refdyn::generate_symbolic(*problem);
    (void)s.c_source();
  } catch (const refdyn::Error&) {
    // a model or task that refdyn refuses (e.g. an initial state it cannot project): expected
  }
  return 0;
}
