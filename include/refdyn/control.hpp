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

/// The reference's RK4 stage values, recorded once (see the header comment).
struct ReferenceStages {
  double t0 = 0, h = 0;
  long steps = 0;                  ///< complete steps recorded
  int n = 0;
  std::vector<double> data;        ///< per step, per stage (4), [q̂, q̂̇, q̂̈] (3n doubles)
  const double* stage(long step, int s) const { return data.data() + ((step * 4 + s) * 3 * n); }
};

/// A planned motion: the reference dynamics integrated, sampled at every step.
struct Plan {
  IntegrationSummary summary;
  std::vector<double> t;
  std::vector<Eigen::VectorXd> x;    ///< [q; q̇; z] per sample
  std::vector<Eigen::VectorXd> qdd;  ///< q̂̈ per sample
  ReferenceStages stages;            ///< filled for RK4
};

/// Solves the reference dynamics from x0 with the given integrator; records samples (and, for
/// RK4, the stage values used by simulate_closed_loop). summary.max_constraint_residual is the
/// largest |Φ| / |c| over the samples with t >= residual_from.
/// `progress`, when given, is called with the time of every sample (e.g. for a progress bar).
Plan plan_motion(ReferenceDynamics& rd, const Eigen::VectorXd& x0, const IntegratorOptions& options,
                 double residual_from = 0.0, const std::function<void(double)>& progress = {});

struct ClosedLoopOptions {
  IntegratorOptions integrator;      ///< must match the plan's RK4 grid when method is RK4
  Eigen::VectorXd effort_limit;      ///< optional per-joint |τ| limit (saturation); empty: none
  std::function<void(double)> progress;  ///< optional: called with the time of every sample
};

struct ClosedLoopResult {
  IntegrationSummary summary;
  std::vector<double> t;
  std::vector<Eigen::VectorXd> x;    ///< plant state [q; q̇; z_plant] per sample
  std::vector<Eigen::VectorXd> tau;  ///< applied (saturated) τ per sample
  std::vector<Eigen::VectorXd> q_ref;
  std::vector<Eigen::VectorXd> qd_ref;
  long saturated_samples = 0;        ///< samples where at least one joint was saturated
};

/// Simulates the plant (model + plant_forces) under `controller` tracking `plan` from x0_plant
/// = [q; q̇; z_plant]. RK4: replays plan.stages (options.integrator must have the same t0, step,
/// and t1 ≤ the plan's end). Dormand–Prince: integrates the reference jointly (needs `rd`).
ClosedLoopResult simulate_closed_loop(const Model& plant, const ForceSet& plant_forces, Controller& controller,
                                      const Plan& plan, ReferenceDynamics* rd, const Eigen::VectorXd& x0_plant,
                                      const ClosedLoopOptions& options);

}  // namespace refdyn
