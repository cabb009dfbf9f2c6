// Consumer of the installed refdyn package (see tests/consumer/CMakeLists.txt). Builds a
// planar 2R arm from a DH table and checks against closed forms: the mass matrix M(q), the
// gravity vector g(q), the end-effector position and the body pseudo-inertias (a 4×4 Eigen
// matrix returned by value from the library: the layout-sensitive case; Data's matrices are
// allocated by the library and freed here: the allocator-sensitive case). Prints
// "refdyn consumer: OK ..." and exits 0 when everything agrees, else names the mismatch and
// exits 1. Uses only the stable headers model.hpp, recursive_dynamics.hpp, kinematics.hpp.
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

#include <cmath>
#include <cstdio>
#include <vector>

namespace {

int failures = 0;

void check(const char* what, double got, double expected) {
  const double tol = 1e-12 * (1.0 + std::abs(expected));
  if (!(std::abs(got - expected) <= tol)) {
    std::printf("MISMATCH %s: got %.17g, expected %.17g\n", what, got, expected);
    ++failures;
  }
}

// A user struct holding library types next to a fixed-size vectorizable Eigen member: its
// layout must be the same as the library's view of Data/Model (EIGEN_MAX_ALIGN_BYTES).
struct Holder {
  char tag = 'x';
  refdyn::Mat4 H = refdyn::Mat4::Zero();
  double after = 42.0;
};

}  // namespace

int main() {
  using namespace refdyn;
  const double l1 = 0.7, l2 = 0.5, r1 = 0.3, r2 = 0.2, m1 = 2.0, m2 = 1.5, I1 = 0.11, I2 = 0.07, g0 = 9.81;
  std::vector<DHRow> rows(2);
  const double l[2] = {l1, l2}, r[2] = {r1, r2}, m[2] = {m1, m2}, I[2] = {I1, I2};
  for (int i = 0; i < 2; ++i) {
    rows[i].a = l[i];
    rows[i].name = "j" + std::to_string(i + 1);
    rows[i].inertia.mass = m[i];
    // Standard DH: the link frame sits at the distal end, x along the link.
    rows[i].inertia.com = Vec3(r[i] - l[i], 0.0, 0.0);
    rows[i].inertia.I_com = Eigen::Vector3d(0.01, I[i], I[i]).asDiagonal();  // a slender link along x
  }
  ModelDescription d = from_dh(rows, DHConvention::Standard, "planar_2r");
  d.gravity = Vec3(0.0, -g0, 0.0);  // in the plane of motion
  d.add_point("E", d.links[1].name, Vec3::Zero());
  const Model model = build_model(d);
  Data data(model);

  std::vector<Holder> holders(3);
  for (const double q1 : {0.3, -1.1, 2.4}) {
    for (const double q2 : {0.0, 0.8, -2.0}) {
      Eigen::VectorXd q(2);
      q << q1, q2;
      const Eigen::MatrixXd& M = mass_matrix(model, data, q);
      const double c2 = std::cos(q2);
      check("M11", M(0, 0), I1 + I2 + m1 * r1 * r1 + m2 * (l1 * l1 + r2 * r2 + 2 * l1 * r2 * c2));
      check("M12", M(0, 1), I2 + m2 * (r2 * r2 + l1 * r2 * c2));
      check("M21", M(1, 0), I2 + m2 * (r2 * r2 + l1 * r2 * c2));
      check("M22", M(1, 1), I2 + m2 * r2 * r2);
      const Eigen::VectorXd& g = gravity_forces(model, data, q);
      check("g1", g(0), g0 * ((m1 * r1 + m2 * l1) * std::cos(q1) + m2 * r2 * std::cos(q1 + q2)));
      check("g2", g(1), g0 * m2 * r2 * std::cos(q1 + q2));
      forward_kinematics(model, data, q);
      const Vec3 e = point_position(model, data, model.point_index("E"));
      check("E_x", e.x(), l1 * std::cos(q1) + l2 * std::cos(q1 + q2));
      check("E_y", e.y(), l1 * std::sin(q1) + l2 * std::sin(q1 + q2));
      check("E_z", e.z(), 0.0);
    }
  }
  // Pseudo-inertia H = [[J, m c], [m cᵀ, m]] in the body frame (the joint frame after the
  // motion: the centre of mass is at (r_i, 0, 0) there).
  for (int i = 0; i < 2; ++i) {
    holders[i].H = model.pseudo_inertia(i);
    check("H(3,3) = m", holders[i].H(3, 3), m[i]);
    check("H(0,3) = m r", holders[i].H(0, 3), m[i] * r[i]);
    check("H(3,0) = m r", holders[i].H(3, 0), m[i] * r[i]);
    check("H(1,3) = 0", holders[i].H(1, 3), 0.0);
    check("holder.after", holders[i].after, 42.0);
  }
  std::printf("refdyn consumer: %s (EIGEN_MAX_ALIGN_BYTES=%d, EIGEN_DEFAULT_ALIGN_BYTES=%d, alignof(Mat4)=%zu, AVX=%d)\n",
              failures == 0 ? "OK" : "FAILED", EIGEN_MAX_ALIGN_BYTES, EIGEN_DEFAULT_ALIGN_BYTES, alignof(Mat4),
#ifdef __AVX__
              1
#else
              0
#endif
  );
  return failures == 0 ? 0 : 1;
}
