#pragma once
// Seeded standard-DH tables shared by the refdyn side and the KDL side of the benchmark.
// Plain data only (no Eigen, no KDL): this header is included by translation units compiled
// with -march=native (refdyn) and without it (the KDL peer).

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace refdyn_bench {

/// One row of a standard DH table plus the link's mass properties in the DH link frame:
/// T_i = T_{i-1} · Rz(θ + q) · Tz(d) · Tx(a) · Rx(α)   (revolute)
/// T_i = T_{i-1} · Rz(θ) · Tz(d + q) · Tx(a) · Rx(α)   (prismatic)
struct DHLink {
  bool prismatic = false;
  double theta = 0, d = 0, a = 0, alpha = 0;
  double mass = 0;
  std::array<double, 3> com{};   ///< centre of mass in the link frame [m]
  std::array<double, 9> I_com{}; ///< inertia about the COM, link axes, row-major [kg m²]
  double armature = 0;           ///< rotor inertia reflected to the joint (refdyn's armature, KDL's joint inertia)
};

struct DHTable {
  std::string name;
  std::vector<DHLink> links;
  std::array<double, 3> gravity{0.0, 0.0, -9.81};
};

/// The paper's three-link manipulator (same numbers as src/paper_manipulator.cpp; the
/// benchmark's start-up check compares the two).
DHTable paper_table();

/// A random serial chain with `dof` joints: about a third prismatic, random θ, d, a, α,
/// masses, centre-of-mass offsets and full (rotated) inertia tensors, so that M is full.
/// Deterministic for a given (dof, seed).
DHTable random_table(int dof, std::uint32_t seed);

/// `count` random joint-space vectors of size n, scaled by `scale`, concatenated
/// (count × n doubles). Deterministic for a given seed.
std::vector<double> random_states(int n, int count, double scale, std::uint32_t seed);

}  // namespace refdyn_bench
