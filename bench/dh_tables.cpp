#include "dh_tables.hpp"

#include <cmath>
#include <numbers>
#include <random>

namespace refdyn_bench {

DHTable paper_table() {
  constexpr double deg = std::numbers::pi / 180.0;
  DHTable t;
  t.name = "paper3";
  auto link = [](bool prismatic, double theta, double d, double a, double alpha, double m,
                 std::array<double, 3> c, double ixx, double iyy, double izz) {
    DHLink l;
    l.prismatic = prismatic;
    l.theta = theta;
    l.d = d;
    l.a = a;
    l.alpha = alpha;
    l.mass = m;
    l.com = c;
    l.I_com = {ixx, 0, 0, 0, iyy, 0, 0, 0, izz};
    return l;
  };
  t.links.push_back(link(false, 0.0, 0.6, 0.0, -90 * deg, 20.0, {0, 0.3, 0}, 0.6125, 0.025, 0.6125));
  t.links.push_back(link(false, 0.0, 0.0, 0.0, -90 * deg, 8.0, {0, 0, 0.1}, 8 * 0.1648 / 12,
                         8 * 0.1648 / 12, 0.0064));
  t.links.push_back(link(true, 0.0, 0.0, 0.0, 0.0, 3.0, {0, 0, -0.4}, 0.1603, 0.1603, 0.0006));
  t.gravity = {0.0, 0.0, -9.81};
  return t;
}

namespace {
// R = rotation of the unit quaternion (w, x, y, z), row-major.
std::array<double, 9> quat_to_matrix(double w, double x, double y, double z) {
  const double n = std::sqrt(w * w + x * x + y * y + z * z);
  w /= n, x /= n, y /= n, z /= n;
  return {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
          2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
          2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
}
}  // namespace

DHTable random_table(int dof, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ang(-std::numbers::pi, std::numbers::pi), len(-0.5, 0.5),
      uni(0.0, 1.0), mass(0.5, 5.0), com(-0.2, 0.2), side(0.05, 0.5);
  std::normal_distribution<double> nrm(0.0, 1.0);
  DHTable t;
  t.name = "chain" + std::to_string(dof);
  for (int i = 0; i < dof; ++i) {
    DHLink l;
    l.prismatic = uni(rng) < 0.3;
    l.theta = ang(rng);
    l.d = len(rng);
    l.a = len(rng);
    l.alpha = ang(rng);
    l.mass = mass(rng);
    l.com = {com(rng), com(rng), com(rng)};
    // A box of random sides (triangle inequality holds), rotated: I = R diag Rᵀ.
    const double sa = side(rng), sb = side(rng), sc = side(rng);
    const double diag[3] = {l.mass * (sb * sb + sc * sc) / 12, l.mass * (sa * sa + sc * sc) / 12,
                            l.mass * (sa * sa + sb * sb) / 12};
    const double w = nrm(rng), x = nrm(rng), y = nrm(rng), z = nrm(rng);
    const auto R = quat_to_matrix(w, x, y, z);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        double s = 0;
        for (int k = 0; k < 3; ++k) s += R[3 * r + k] * diag[k] * R[3 * c + k];
        l.I_com[3 * r + c] = s;
      }
    for (int r = 0; r < 3; ++r)  // exact symmetry
      for (int c = r + 1; c < 3; ++c) l.I_com[3 * c + r] = l.I_com[3 * r + c];
    t.links.push_back(l);
  }
  t.gravity = {0.0, 0.0, -9.81};
  return t;
}

std::vector<double> random_states(int n, int count, double scale, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-scale, scale);
  std::vector<double> v(static_cast<size_t>(n) * count);
  for (double& x : v) x = u(rng);
  return v;
}

}  // namespace refdyn_bench
