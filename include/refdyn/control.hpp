#pragma once
/// Tracking control of a planned motion on the unconstrained plant (paper section 3).
///
/// Controller interface: time, plant state (q, q̇) and reference (q̂, q̂̇, q̂̈) in, joint
/// torques/forces τ out. The plant is the unconstrained model with its own force elements
/// and initial state:  M(q) q̈ + c(q, q̇) + g(q) = τ + Q_plant(t, q, q̇, z).
///
/// Reference at every integrator stage. The reference dynamics is autonomous (it does not
/// depend on the plant), so integrating [reference; plant] jointly with RK4 is identical to
/// recording the reference's own RK4 stage values (q̂, q̂̇, q̂̈ at t, t+h/2, t+h/2, t+h of every
/// step) once, and replaying them to each plant. simulate_closed_loop does the latter for RK4
/// (the reference is computed once for any number of closed loops) and the joint integration
/// for Dormand–Prince. Either way the controller never sees a stale or interpolated sample.

#include "refdyn/force_elements.hpp"
#include "refdyn/integrators.hpp"
#include "refdyn/model.hpp"
#include "refdyn/reference_dynamics.hpp"

#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace refdyn {

struct ReferenceSample {
  const Eigen::VectorXd& q;
  const Eigen::VectorXd& qd;
  const Eigen::VectorXd& qdd;
};

class Controller {
 public:
  virtual ~Controller() = default;
  virtual std::string name() const = 0;
  /// Number of the controller's own states xc (e.g. a PID's error integrals); they are part of
  /// the closed-loop state vector [q; q̇; z_plant; xc] and start at zero.
  virtual int num_states() const { return 0; }
  virtual std::vector<std::string> state_names() const { return {}; }
  /// τ (size nq) from time, plant state and reference. May use internal workspace.
  virtual void compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
                       Eigen::VectorXd& tau) = 0;
  /// The same, when the caller has already evaluated M(q) and c(q, q̇) + g(q) of `model` at this
  /// (q, q̇) into `dynamics` (dynamics.M, dynamics.nle). A controller whose own model is that
  /// same Model object may use them instead of recomputing; the closed loop passes the plant's.
  /// The default ignores them.
  virtual void compute_with_dynamics(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                     const ReferenceSample& ref, const Model& model, const Data& dynamics,
                                     Eigen::VectorXd& tau) {
    compute(t, q, qd, ref, tau);
  }
  /// True when compute_with_dynamics uses the M and c + g of `model` it is given (the closed
  /// loop then evaluates them for the plant and solves M q̈ = … by Cholesky; otherwise a plant
  /// from kAbaFrom coordinates on takes the articulated-body algorithm, recursive_dynamics.hpp).
  virtual bool reuses_dynamics(const Model& /*model*/) const { return false; }
  /// The entry point of the closed loop: as compute_with_dynamics (`dynamics` may be null:
  /// not evaluated), plus the controller's states xc and their derivatives xc_dot (written;
  /// null when the caller needs τ only). The default has no states.
  virtual void compute_with_state(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                  const ReferenceSample& ref, const double* xc, double* xc_dot, const Model& model,
                                  const Data* dynamics, Eigen::VectorXd& tau) {
    if (dynamics)
      compute_with_dynamics(t, q, qd, ref, model, *dynamics, tau);
    else
      compute(t, q, qd, ref, tau);
  }
};

/// Feedback linearization + PD, paper (3.2)–(3.4):
///   τ = M(q) u + c(q, q̇) + g(q),   u_i = q̂̈_i − 2δ_i ė_i − δ_i² e_i,   e = q − q̂.
/// With a perfect model each error obeys ë + 2δė + δ²e = 0: e(t) = (e0 + (ė0 + δe0) t) e^(−δt).
class ComputedTorquePD final : public Controller {
 public:
  /// `model` is the controller's model of the plant (kept by reference); delta: one gain per joint [1/s].
  ComputedTorquePD(const Model& model, Eigen::VectorXd delta);
  std::string name() const override { return "computed_torque_pd"; }
  void compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
               Eigen::VectorXd& tau) override;
  /// Uses dynamics.M and dynamics.nle when `model` is this controller's model (same object).
  bool reuses_dynamics(const Model& model) const override { return &model == &model_; }
  void compute_with_dynamics(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                             const ReferenceSample& ref, const Model& model, const Data& dynamics,
                             Eigen::VectorXd& tau) override;
 private:
  void outer_loop(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& r);  // u_
  const Model& model_;
  Data data_;
  Eigen::VectorXd delta_, u_;
};

/// PD + gravity compensation: τ = g(q) − K_p e − K_d ė.
class PDGravity final : public Controller {
 public:
  PDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd kd);
  std::string name() const override { return "pd_gravity"; }
  void compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
               Eigen::VectorXd& tau) override;
 private:
  const Model& model_;
  Data data_;
  Eigen::VectorXd kp_, kd_;
};

/// PID + gravity compensation: τ = g(q) − K_p e − K_i ξ − K_d ė with ξ̇ = e (one integral
/// state per joint, in the closed-loop state vector). The integral removes the steady error
/// that a constant disturbance leaves under PD (−F/K_p).
class PIDGravity final : public Controller {
 public:
  PIDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd ki, Eigen::VectorXd kd);
  std::string name() const override { return "pid_gravity"; }
  int num_states() const override { return model_.nv; }
  std::vector<std::string> state_names() const override;
  /// τ with zero integral states.
  void compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
               Eigen::VectorXd& tau) override;
  void compute_with_state(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
                          const double* xc, double* xc_dot, const Model& model, const Data* dynamics,
                          Eigen::VectorXd& tau) override;
 private:
  const Model& model_;
  Data data_;
  Eigen::VectorXd kp_, ki_, kd_;
};

/// The reference's RK4 stage values, recorded once (see the header comment).
struct ReferenceStages {
  double t0 = 0, h = 0;
  long steps = 0;                  ///< complete steps recorded
  int n = 0;
  std::vector<double> data;        ///< per step, per stage (4), [q̂, q̂̇, q̂̈] (3n doubles)
  const double* stage(long step, int s) const { return data.data() + ((step * 4 + s) * 3 * n); }
};

/// A recorded motion, one entry per output sample. What is recorded depends on the recorder:
/// a plan fills the reference-dynamics series (q̈, Φ, Φ̇, λ, Q_c, efforts), a closed loop the
/// tracking series (τ, q̂, q̂̇); series a recorder does not fill stay empty. Names say what the
/// columns of each vector series are; io/trajectory_io.hpp writes any Trajectory as CSV.
struct Trajectory {
  // ---- layout ----
  std::vector<std::string> joints;          ///< q, q̇, q̈, Q_c, efforts, τ, q̂: one per joint
  std::vector<std::string> state_names;     ///< the states after [q; q̇] in x (force elements, controller)
  std::vector<std::string> points;          ///< recorded points (3 columns each: x, y, z in the world)
  std::vector<std::string> constraint_rows; ///< Φ, Φ̇, λ: one per constraint row
  std::vector<char> material_row;           ///< per constraint row: material (1) or programmed (0)
  std::vector<std::string> target_signals;  ///< functions of t prescribed by constraints (record_as)
  std::vector<std::string> force_signals;   ///< quantities of force elements (a drive's ψ_dr, torque)

  // ---- samples ----
  std::vector<double> t;
  std::vector<Eigen::VectorXd> x;           ///< [q; q̇; states]
  std::vector<Eigen::VectorXd> qdd;         ///< q̈ (plans)
  std::vector<Eigen::VectorXd> point_positions;  ///< 3 × points
  std::vector<Eigen::VectorXd> targets, forces;  ///< target_signals, force_signals values
  std::vector<Eigen::VectorXd> phi, phid, lambda;  ///< constraint rows (plans)
  std::vector<Eigen::VectorXd> Qc;          ///< Q_c = M q̈ − F = −Aᵀλ, all rows (plans)
  /// What the actuators must deliver: actuator force elements (drives, efforts) plus the forces
  /// of the programmed constraints (plans). Feasibility checks this against effort limits.
  std::vector<Eigen::VectorXd> actuator_effort;
  /// Reaction forces of the material constraints (pins, rolling without slip): carried by the
  /// structure, not by the actuators (plans; empty when there are no material constraints).
  std::vector<Eigen::VectorXd> reaction_effort;
  std::vector<Eigen::VectorXd> tau, q_ref, qd_ref;  ///< applied τ and the reference (closed loops)

  size_t size() const { return t.size(); }
  int nq() const { return static_cast<int>(joints.size()); }
};

/// A planned motion: the reference dynamics integrated and recorded at every output sample.
struct Plan : Trajectory {
  IntegrationSummary summary;
  ReferenceStages stages;            ///< filled for RK4
};

/// What plan_motion records besides the state (model point indices, e.g. a scenario's outputs).
struct RecordOptions {
  std::vector<int> points;
  /// The plan stops at the first output sample (t >= residual_from) whose constraint residual
  /// max |Phi| exceeds this (or is not a number): that sample is not recorded, the plan ends at
  /// the one before with status ResidualExceeded. Infinity: no check (the library default).
  double residual_tolerance = std::numeric_limits<double>::infinity();
};

/// Solves the reference dynamics from x0 with the given integrator and records it: at every
/// output sample one evaluation of the reference dynamics gives q̈, Φ, Φ̇, λ, Q_c, the efforts,
/// the recorded points and signals; for RK4 the integrator's stage hook also records the stage
/// values used by simulate_closed_loop. summary.max_constraint_residual is the largest |Φ| / |c|
/// over the samples with t >= residual_from. `progress`, when given, is called with the time
/// of every sample (e.g. for a progress bar).
Plan plan_motion(ReferenceDynamics& rd, const Eigen::VectorXd& x0, const IntegratorOptions& options,
                 double residual_from = 0.0, const std::function<void(double)>& progress = {},
                 const RecordOptions& record = {});

struct ClosedLoopOptions {
  IntegratorOptions integrator;      ///< must match the plan's RK4 grid when method is RK4
  Eigen::VectorXd effort_limit;      ///< optional per-joint |τ| limit (saturation); empty: none
  std::function<void(double)> progress;  ///< optional: called with the time of every sample
  std::vector<int> points;           ///< model points whose positions are recorded
};

/// A closed-loop run: x = [q; q̇; z_plant; xc] (xc: the controller's states), τ, q̂, q̂̇.
struct ClosedLoopResult : Trajectory {
  IntegrationSummary summary;
  long saturated_samples = 0;        ///< samples where at least one joint was saturated
};

/// Simulates the plant (model + plant_forces) under `controller` tracking `plan` from x0_plant
/// = [q; q̇; z_plant] (the controller's states, if any, start at zero; x0_plant may also carry
/// them). RK4: replays plan.stages through the integrator's stage hook (options.integrator must
/// have the same t0, step, and t1 ≤ the plan's end). Dormand–Prince: integrates the reference
/// jointly (needs `rd`).
ClosedLoopResult simulate_closed_loop(const Model& plant, const ForceSet& plant_forces, Controller& controller,
                                      const Plan& plan, ReferenceDynamics* rd, const Eigen::VectorXd& x0_plant,
                                      const ClosedLoopOptions& options);

}  // namespace refdyn
