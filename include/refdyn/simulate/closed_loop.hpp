#pragma once
/// Tracking control of a planned motion on the plant (paper section 3): simulate_closed_loop
/// runs a Controller (controllers.hpp) against a Plan (trajectory.hpp).
///
/// Controller interface: time, plant state (q, q̇) and reference (q̂, q̂̇, q̂̈) in, motor efforts
/// τ out (0 at joints without a motor). The plant is the mechanism as built, with its own force
/// elements and initial state:
///   - without material constraints:  M(q) q̈ + c(q, q̇) + g(q) = τ + Q_plant(t, q, q̇, z);
///   - with material rows (ClosedLoopOptions::material: loop closures, rolling without slip,
///     gear couplings): the same equations with the reactions −Aᵀλ of those rows, solved by the
///     planner's machinery (ReferenceDynamics over the material rows alone, with τ among its
///     applied forces: KKT or projection, Baumgarte or projection stabilisation). Programmed
///     rows never enter the plant: the motors realise them.
///
/// Reference at every integrator stage. The reference dynamics is autonomous (it does not
/// depend on the plant), so integrating [reference; plant] jointly with RK4 is identical to
/// recording the reference's own RK4 stage values (q̂, q̂̇, q̂̈ at t, t+h/2, t+h/2, t+h of every
/// step) once, and replaying them to each plant. simulate_closed_loop does the latter for RK4
/// (the reference is computed once for any number of closed loops) and the joint integration
/// for Dormand–Prince. Either way the controller never sees a stale or interpolated sample.

#include "refdyn/forces/force_elements.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/simulate/controllers.hpp"
#include "refdyn/simulate/integrators.hpp"
#include "refdyn/simulate/planner.hpp"
#include "refdyn/simulate/trajectory.hpp"

#include <cstddef>
#include <functional>
#include <vector>

namespace refdyn {

struct ClosedLoopOptions {
  IntegratorOptions integrator;      ///< must match the plan's RK4 grid when method is RK4
  Eigen::VectorXd effort_limit;      ///< optional per-joint |τ| limit (saturation); empty: none
  std::function<void(double)> progress;  ///< optional: called with the time of every sample
  std::vector<int> points;           ///< model points whose positions are recorded
  /// The plant's material constraints (rows of origin material, holonomic or first order);
  /// null or empty: an unconstrained plant. Kept by reference.
  const ConstraintSet* material = nullptr;
  /// With material rows: the plant's solver, stabilisation and Baumgarte gains (the partition is
  /// the controller's assigned coordinates, Controller::actuation().independent).
  ReferenceDynamicsOptions plant;
};

/// A closed-loop run: x = [q; q̇; z_plant; xc] (xc: the controller's states), τ, q̂, q̂̇. With
/// material rows also, per sample, their Φ (or c), Φ̇, λ and reactions −Aᵀλ (Trajectory::phi,
/// phid, lambda, reaction_effort) and the largest residual max |Φ|, |c| over the run.
struct ClosedLoopResult : Trajectory {
  IntegrationSummary summary;
  long saturated_samples = 0;        ///< samples where at least one joint was saturated
  double max_material_residual = 0;  ///< max over samples and material rows of |Φ| and |c|
  /// The start's correction onto the material rows (track_experiment: independent coordinates
  /// kept, dependent ones solved): max |δq|, max |δq̇|; zero without material rows.
  double initial_correction_q = 0, initial_correction_qd = 0;
};

/// Simulates the plant (model + plant_forces) under `controller` tracking `plan` from x0_plant
/// = [q; q̇; z_plant] (the controller's states, if any, start at zero; x0_plant may also carry
/// them). RK4: replays plan.stages through the integrator's stage hook (options.integrator must
/// have the same t0, step, and t1 ≤ the plan's end). Dormand–Prince and BDF: integrate the
/// reference jointly (need the `planner` that made the plan: its state and derivative give q̂,
/// q̂̇, q̂̈ through Planner::reference; BDF also its Jacobian, Planner::jacobian).
ClosedLoopResult simulate_closed_loop(const Model& plant, const ForceSet& plant_forces, Controller& controller,
                                      const Plan& plan, Planner* planner, const Eigen::VectorXd& x0_plant,
                                      const ClosedLoopOptions& options);
/// The joint system that Dormand–Prince and BDF integrate, X = [x_ref; q; q̇; z_plant; xc] (the
/// planner's state, then the plant's): its derivative dX and, when J is given, its exact
/// Jacobian ∂Ẋ/∂X (dual numbers through the controller, the plant and the planner; docs/implicit.md).
/// For tests and tools; allocates its workspace per call.
void closed_loop_derivative(const Model& plant, const ForceSet& plant_forces, Controller& controller, Planner& planner,
                            const Eigen::VectorXd& effort_limit, double t, const Eigen::VectorXd& X,
                            Eigen::VectorXd& dX, Eigen::MatrixXd* J = nullptr);
/// The same with the plant of `options` (its material rows and effort limits).
void closed_loop_derivative(const Model& plant, const ForceSet& plant_forces, Controller& controller, Planner& planner,
                            const ClosedLoopOptions& options, double t, const Eigen::VectorXd& X, Eigen::VectorXd& dX,
                            Eigen::MatrixXd* J = nullptr);
/// The same with a ReferenceDynamics (order ≤ 2) as the planner (null: RK4 replay only).
ClosedLoopResult simulate_closed_loop(const Model& plant, const ForceSet& plant_forces, Controller& controller,
                                      const Plan& plan, ReferenceDynamics* rd, const Eigen::VectorXd& x0_plant,
                                      const ClosedLoopOptions& options);
/// RK4 replay only (no planner).
inline ClosedLoopResult simulate_closed_loop(const Model& plant, const ForceSet& plant_forces, Controller& controller,
                                             const Plan& plan, std::nullptr_t, const Eigen::VectorXd& x0_plant,
                                             const ClosedLoopOptions& options) {
  return simulate_closed_loop(plant, plant_forces, controller, plan, static_cast<Planner*>(nullptr), x0_plant, options);
}

}  // namespace refdyn
