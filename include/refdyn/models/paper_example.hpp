#pragma once
/// The paper's worked example, every number fixed (docs/paper_example.md): the three-link
/// manipulator with a flexible drive on joint 1, LuGre friction in all joints, and the
/// programmed constraints
///   Φ1 = (x_E/a)² + (y_E/b)² − 1,   a = 0.5 cos 45°, b = 0.25
///   Φ2 = z_E − z_a(t),  z_a = h1 + 0.5 sin 45° + Δz (1 − cos(2πt/T_z))/2, Δz = 0.1, T_z = 5
/// with independent coordinate ψ1, dependent (ψ2, z3), Baumgarte α = 100, β = 50.

#include "refdyn/constraints/constraints.hpp"
#include "refdyn/forces/force_elements.hpp"
#include "refdyn/simulate/integrators.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/reference/reference_dynamics.hpp"

#include <memory>
#include <vector>

namespace refdyn::models {

struct PaperExampleParams {
  double ellipse_a = 0.35355339059327373;  ///< 0.5 cos 45° [m]
  double ellipse_b = 0.25;                 ///< [m]
  double z_amplitude = 0.1;                ///< Δz [m]
  double z_period = 5.0;                   ///< T_z [s]
  double drive_rise = 6.283185307179586;   ///< ψ_S = 2π [rad]
  double drive_duration = 5.0;             ///< t_S [s]
  FlexibleDriveParams drive{1e4, 70.0};
  LuGreParams lugre_rot{0.1, 0.2, 5.0, 0.025, 0.0, 0.175};   ///< joints 1, 2
  LuGreParams lugre_lin{0.1, 0.2, 1.0, 0.02, 0.0, 0.001};    ///< joint 3
  bool with_friction = true;
  bool with_drive = true;
  double alpha = 100.0, beta = 50.0;
  double elevation0 = 0.7853981633974483;  ///< initial elevation ε of the sliding link (45°)
  double z3_0 = 0.5;                       ///< initial slider extension [m]
  double t1 = 5.0, step = 1e-3;
  /// Build Φ1, Φ2 from symbolic expressions (expression_constraint) instead of the
  /// hand-written ready-made kinds; the results agree to rounding (tested).
  bool expression_constraints = false;
  /// Joint limits for the feasibility report (the paper gives none; default: unlimited).
  std::vector<JointLimits> limits;
};

/// Everything needed to plan the paper's motion; members own what ReferenceDynamics refers to.
struct PaperExample {
  explicit PaperExample(const PaperExampleParams& p = {});
  PaperExampleParams params;
  Model model;
  ForceSet forces;
  ConstraintSet constraints;
  std::shared_ptr<const FlexibleDrive> drive;      ///< null when params.with_drive is false
  ReferenceDynamicsOptions options() const;
  Eigen::VectorXd q0() const;                      ///< [0, 270° − ε, z3_0]
  IntegratorOptions integrator() const;            ///< RK4, h, [0, t1]
  TimeFunctionPtr z_a;                             ///< the prescribed height z_a(t)
};

}  // namespace refdyn::models
