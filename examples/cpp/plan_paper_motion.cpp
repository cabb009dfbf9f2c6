// The C++ API in one page: plan the paper's motion (docs/paper_example.md §5) and write a CSV
// with t, q, q̇, q̈, bristle states, E, Φ, Φ̇, drive torque and constraint forces.
//   build/examples/plan_paper_motion [out.csv]
#include "refdyn/refdyn.hpp"  // the whole API (or only the headers used: simulate/plan.hpp, io/output.hpp, ...)

#include <cstdio>

int main(int argc, char** argv) {
  using namespace refdyn;
  models::PaperExample ex;  // model, flexible drive, LuGre friction, ellipse + height constraints
  ReferenceDynamics rd(ex.model, ex.forces, ex.constraints, ex.options());  // ψ1 independent, α=100, β=50
  const Eigen::VectorXd x0 = rd.make_state(ex.q0(), Eigen::VectorXd::Zero(3));
  const Plan plan = plan_motion(rd, x0, {ex.integrator(), /*residual_from=*/0.5});  // RK4, h = 1e-3, 0..5 s
  if (!plan.summary.ok()) {
    std::fprintf(stderr, "plan stopped: %s\n", plan.summary.message.c_str());
    return 4;
  }
  io::CsvTable csv;
  csv.header = {"t", "psi1", "psi2", "z3", "dpsi1", "dpsi2", "dz3", "ddpsi1", "ddpsi2", "ddz3", "z_psi1", "z_psi2",
                "z_z3", "E_x", "E_y", "E_z", "phi1", "phi2", "phid1", "phid2", "tau_drive", "Qc1", "Qc2", "Qc3"};
  Eigen::VectorXd dx(rd.state_size());
  const int E = ex.model.point_index("E");
  for (size_t k = 0; k < plan.t.size(); ++k) {
    const double t = plan.t[k];
    const Eigen::VectorXd& x = plan.x[k];
    rd.derivative(t, x, dx);  // fills q̈, Φ, Φ̇, E's kinematics and the constraint forces
    const auto& c = rd.constraints();
    const Vec3 r = c.points[E].r;
    const double tau = ex.drive->torque(t, x.head(3), x.segment(3, 3));
    csv.add_row({t, x[0], x[1], x[2], x[3], x[4], x[5], dx[3], dx[4], dx[5], x[6], x[7], x[8], r.x(), r.y(), r.z(),
                 c.phi[0], c.phi[1], c.phid[0], c.phid[1], tau, rd.constraint_force()[0], rd.constraint_force()[1],
                 rd.constraint_force()[2]});
  }
  const std::string out = argc > 1 ? argv[1] : "paper_plan.csv";
  io::write_csv_atomic(out, csv);
  std::printf("psi1(1 s) = %.8f rad, z3(1 s) = %.8f m, max |Phi| over 0.5-5 s = %.2e; wrote %s\n", plan.x[1000][0],
              plan.x[1000][2], plan.summary.max_constraint_residual, out.c_str());
  return 0;
}
