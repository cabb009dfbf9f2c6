#pragma once
/// Force elements: generalized forces Q(t, q, q̇, z) acting in the joints, some with internal
/// states z (LuGre bristles) integrated as part of the state vector x = [q, q̇, z].
/// Sign convention: M q̈ + c + g = Q (+ controls, + constraint forces); Q is what the element
/// applies to the joint (a friction torque opposes the motion: Q = −(…)).

#include "refdyn/multibody/dual.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/expression/formula.hpp"
#include "refdyn/expression/time_function.hpp"

#include <algorithm>
#include <memory>
#include <string>
#include <vector>

namespace refdyn {

class ForceElement {
 public:
  virtual ~ForceElement() = default;
  virtual std::string name() const = 0;
  virtual int num_states() const { return 0; }
  /// Adds the element's generalized force to Q (size nq). z: its states, zdot: their
  /// derivatives (written). dQ_dqd (nq×nq, optional): adds ∂Q/∂q̇ (exact).
  virtual void apply(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double* z,
                     Eigen::VectorXd& Q, double* zdot, Eigen::MatrixXd* dQ_dqd) const = 0;
  /// apply() over dual numbers, for the exact Jacobians of implicit integration (∂Q and ∂ż with
  /// respect to q, q̇ and z along the seeded directions): adds the element's force to Q[0, nq) and
  /// writes its state rates to zdot. Every kind refdyn provides has it; the default throws an
  /// Error naming the element (a user-defined element without it cannot be integrated by BDF).
  virtual void apply_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* z,
                          JacobianScalar* Q, JacobianScalar* zdot) const;
  /// Whether apply_dual() is provided, and whether add_rate_with_states() gives the rate: known
  /// when the element is built, so that build_problem refuses an element without them under
  /// method: bdf (exact derivatives) or in a jerk-level problem (the rate) with the entry's
  /// location, instead of a throw in the middle of a run. Every element written as a law
  /// (ForceLaw below) has both; a hand-written element overrides them with what it implements.
  virtual bool exact_derivatives() const { return false; }
  virtual bool has_rate() const { return false; }
  /// Adds the rate of the element's force along the motion, Q̇ = ∂Q/∂t + ∂Q/∂q q̇ + ∂Q/∂q̇ q̈
  /// (exact), to Qdot and returns true; the default provides none and returns false. Needed by
  /// jerk-level problems (p = 3, jerk.hpp), which reject elements without it (and elements with
  /// states). Damping, spring, effort and the flexible drive provide it.
  virtual bool add_rate(double /*t*/, const Eigen::VectorXd& /*q*/, const Eigen::VectorXd& /*qd*/,
                        const Eigen::VectorXd& /*qdd*/, Eigen::VectorXd& /*Qdot*/) const {
    return false;
  }
  /// The rate of the force with the element's states: Q̇ = ∂Q/∂t + ∂Q/∂q q̇ + ∂Q/∂q̇ q̈ + ∂Q/∂z ż
  /// (exact) added to Qdot, with z the states and zdot their rates at the same point; returns
  /// false if the element provides none. The default: add_rate() for an element without states.
  /// LuGre friction (states, no explicit time) provides it through apply_dual. Needed by
  /// jerk-level problems (state [q; q̇; q̈; z]).
  virtual bool add_rate_with_states(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                    const Eigen::VectorXd& qdd, const double* /*z*/, const double* /*zdot*/,
                                    Eigen::VectorXd& Qdot) const {
    return num_states() == 0 && add_rate(t, q, qd, qdd, Qdot);
  }
  /// Name of each state (for CSV headers).
  virtual std::vector<std::string> state_names() const { return {}; }
  /// True for actuators (drives, prescribed efforts): their force is delivered by the joint's
  /// motor and counts in the feasibility report's required effort.
  virtual bool actuator() const { return false; }
  /// Named quantities recorded in trajectories besides the force (e.g. a drive's ψ_dr and
  /// torque), and their values at (t, q, q̇, z) written to out[0 .. signal_names().size()).
  virtual std::vector<std::string> signal_names() const { return {}; }
  virtual void signals(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double* z,
                       double* out) const {}

  /// Q as texts of the expression language (symbolic_form.hpp) over the model's joint names:
  /// `rows` with their `joints`, the states' `state_rates`; none for an element without a closed
  /// form. ForceLaw derives it from law<Formula>.
  virtual std::optional<SymbolicForm> symbolic(const Model& /*model*/) const { return std::nullopt; }
  /// Optional label from the scenario (`name:`); suffixes signal names ("psi_dr_<label>").
  std::string label;
};
/// A force element written once, over a scalar S (as a constraint kind is, constraints/law.hpp):
///
///     class MyElement final : public ForceLaw<MyElement> {
///      public:
///       template <class S>
///       void law(const S& t, const S* q, const S* qd, const S* z, S* Q, S* zdot) const;
///     };
///
/// law<S> adds the element's generalized force to Q[0, n) and writes its states' rates ż to
/// zdot[0, num_states()) from t, q, q̇ (n entries each) and its states z. ForceLaw derives:
///   apply()                 law<double>; with dQ_dqd, ∂Q/∂q̇ from law<JacobianScalar> seeded on
///                           q̇ (⌈n / 8⌉ sweeps: only the paper-literal option asks for it)
///   apply_dual()            law<JacobianScalar> at the unseeded time t
///   add_rate_with_states()  law<Dual<1>> seeded along the motion (t with 1, q with q̇, q̇ with
///                           q̈, z with ż): Q̇ = ∂Q/∂t + ∂Q/∂q q̇ + ∂Q/∂q̇ q̈ + ∂Q/∂z ż
///   add_rate()              the same for an element without states (false for one with them:
///                           their rates are needed)
///   symbolic()              law<Formula> (formula.hpp): Q's rows and the states' rates as
///                           texts, the element's scenario numbers as param<S>(n) keeping their
///                           names, its functions of time as the generator's NAME / d_NAME
/// and reports exact_derivatives() and has_rate() true. The scratch of the dual sweeps is per
/// thread and grows once (no allocation after the first call with a given n on a thread).
/// tests/law_test.cpp evaluates every element's text against its law.
template <class Element>
class ForceLaw : public ForceElement {
 public:
  void apply(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double* z, Eigen::VectorXd& Q,
             double* zdot, Eigen::MatrixXd* dQ_dqd) const final {
    self().template law<double>(t, q.data(), qd.data(), z, Q.data(), zdot);
    if (dQ_dqd) add_velocity_jacobian(t, q, qd, z, *dQ_dqd);
  }
  void apply_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* z,
                  JacobianScalar* Q, JacobianScalar* zdot) const final {
    self().template law<JacobianScalar>(JacobianScalar(t), q, qd, z, Q, zdot);
  }
  bool add_rate(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd,
                Eigen::VectorXd& Qdot) const final {
    return this->num_states() == 0 && add_rate_with_states(t, q, qd, qdd, nullptr, nullptr, Qdot);
  }
  bool add_rate_with_states(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd,
                            const double* z, const double* zdot, Eigen::VectorXd& Qdot) const final {
    using D1 = ad::Dual<1>;
    const int n = static_cast<int>(q.size()), nz = this->num_states();
    Sweep<D1>& s = sweep<D1>(n, nz);
    for (int i = 0; i < n; ++i) {
      s.q[i] = D1::variable(q[i], 0, qd[i]);
      s.qd[i] = D1::variable(qd[i], 0, qdd[i]);
      s.Q[i] = D1(0.0);
    }
    for (int k = 0; k < nz; ++k) s.z[k] = D1::variable(z[k], 0, zdot[k]);
    self().template law<D1>(D1::variable(t, 0, 1.0), s.q.data(), s.qd.data(), s.z.data(), s.Q.data(), s.zdot.data());
    for (int i = 0; i < n; ++i)
      if (s.Q[i].d[0] != 0.0) Qdot[i] += s.Q[i].d[0];
    return true;
  }
  bool exact_derivatives() const final { return true; }
  bool has_rate() const final { return true; }
  std::optional<SymbolicForm> symbolic(const Model& model) const final {
    const int n = model.nq, nz = this->num_states();
    std::vector<Formula> q, qd, z, Q(n), zdot(std::max(1, nz));
    for (int i = 0; i < n; ++i) {
      q.push_back(Formula::variable("q(" + model.joint_name[i] + ")"));
      qd.push_back(Formula::variable("qd(" + model.joint_name[i] + ")"));
    }
    for (int k = 0; k < std::max(1, nz); ++k) z.push_back(Formula::variable("z(" + std::to_string(k) + ")"));
    FormulaScope scope;
    try {
      self().template law<Formula>(Formula::variable("t"), q.data(), qd.data(), z.data(), Q.data(), zdot.data());
    } catch (const NoSymbolicForm&) {
      return std::nullopt;
    }
    SymbolicForm form;
    for (int i = 0; i < n; ++i)
      if (!Q[i].is_zero()) form.rows.push_back(Q[i].text()), form.joints.push_back(i);
    for (int k = 0; k < nz; ++k) form.state_rates.push_back(zdot[k].text());
    form.parameters = scope.parameters;
    form.functions = scope.functions;
    form.scenario_texts = scope.scenario_texts;
    return form;
  }

 private:
  const Element& self() const { return static_cast<const Element&>(*this); }
  template <class D>
  struct Sweep {
    std::vector<D> q, qd, z, Q, zdot;
  };
  /// Per-thread scratch of the dual sweeps, sized for n coordinates and nz states.
  template <class D>
  static Sweep<D>& sweep(int n, int nz) {
    thread_local Sweep<D> s;
    const size_t m = static_cast<size_t>(std::max(1, nz));
    if (s.q.size() < static_cast<size_t>(n)) s.q.resize(n), s.qd.resize(n), s.Q.resize(n);
    if (s.z.size() < m) s.z.resize(m), s.zdot.resize(m);
    return s;
  }
  /// dQ_dqd += ∂Q/∂q̇, column block by column block.
  void add_velocity_jacobian(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double* z,
                             Eigen::MatrixXd& dQ) const {
    using D = JacobianScalar;
    const int n = static_cast<int>(q.size()), nz = this->num_states();
    Sweep<D>& s = sweep<D>(n, nz);
    for (int c0 = 0; c0 < n; c0 += kJacobianDirections) {
      const int width = std::min(kJacobianDirections, n - c0);
      for (int i = 0; i < n; ++i) {
        s.q[i] = D(q[i]);
        s.qd[i] = i >= c0 && i < c0 + width ? D::variable(qd[i], i - c0) : D(qd[i]);
        s.Q[i] = D(0.0);
      }
      for (int k = 0; k < nz; ++k) s.z[k] = D(z[k]);
      self().template law<D>(D(t), s.q.data(), s.qd.data(), s.z.data(), s.Q.data(), s.zdot.data());
      for (int i = 0; i < n; ++i)
        for (int k = 0; k < width; ++k) dQ(i, c0 + k) += s.Q[i].d[k];
    }
  }
};

using ForceElementPtr = std::shared_ptr<const ForceElement>;
/// A force element while it is being built: labelled by the caller before it is published as a
/// ForceElementPtr (ForceSet::add).
using NewForceElement = std::shared_ptr<ForceElement>;

/// τ = −b q̇_j.
NewForceElement joint_damping(const Model& model, const std::string& joint, Number b);
/// τ = −k (q_j − q_rest).
NewForceElement joint_spring(const Model& model, const std::string& joint, Number k, Number q_rest = 0.0);
/// τ = f(t): a prescribed joint torque or force.
NewForceElement joint_effort(const Model& model, const std::string& joint, TimeFunctionPtr f);

/// Flexible drive (paper (4.6)): τ = s (ψ_dr(t) − q_j) + d (ψ̇_dr(t) − q̇_j), with the sign that
/// makes q_j follow the drive displacement ψ_dr.
struct FlexibleDriveParams {
  Number stiffness = 1e4;   ///< s [Nm/rad or N/m]
  Number damping = 70.0;    ///< d [Nms/rad or Ns/m]
};
class FlexibleDrive final : public ForceLaw<FlexibleDrive> {
 public:
  FlexibleDrive(const Model& model, const std::string& joint, FlexibleDriveParams p, TimeFunctionPtr profile);
  std::string name() const override { return "flexible_drive(" + joint_name_ + ")"; }
  bool actuator() const override { return true; }
  /// Q_j += τ(t, q_j, q̇_j) (torque_law); no states.
  template <class S>
  void law(const S& t, const S* q, const S* qd, const S* z, S* Q, S* zdot) const;
  /// The drive torque alone.
  double torque(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd) const;
  /// psi_dr (the drive displacement ψ_dr(t)) and tau_drive (its torque), suffixed "_<label>".
  std::vector<std::string> signal_names() const override;
  void signals(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double* z,
               double* out) const override;
  const TimeFunction& profile() const { return *profile_; }
  int joint() const { return j_; }
 private:
  template <class S>
  S torque_law(const S& t, const S& qj, const S& qdj) const;
  int j_;
  std::string joint_name_;
  FlexibleDriveParams p_;
  TimeFunctionPtr profile_;
};

/// LuGre friction (paper (4.7)–(4.8)) in one joint, bristle deflection z as state:
///   ż = q̇ − σ0 |q̇| z / g(q̇),  g(q̇) = μk + (μs − μk) exp(−(q̇/q̇_S)²)
///   τ = −(σ0 z + σ1 ż + σ2 q̇)
struct LuGreParams {
  Number mu_s = 0.1, mu_k = 0.2;      ///< static and kinetic friction levels [Nm or N]
  Number sigma0 = 5.0, sigma1 = 0.025, sigma2 = 0.0;
  Number v_stribeck = 0.175;          ///< Stribeck velocity q̇_S
};
class LuGreFriction final : public ForceLaw<LuGreFriction> {
 public:
  LuGreFriction(const Model& model, const std::string& joint, LuGreParams p);
  /// Defined in lugre.cpp: the key function, so the vtable and ForceLaw's apply (which inlines
  /// law<double>, defined there) are emitted in that file only.
  std::string name() const override;
  int num_states() const override { return 1; }
  std::vector<std::string> state_names() const override { return {"z_" + joint_name_}; }
  /// ż and τ above, in the joint.
  template <class S>
  void law(const S& t, const S* q, const S* qd, const S* z, S* Q, S* zdot) const;
  const LuGreParams& params() const { return p_; }
  int joint() const { return j_; }
 private:
  int j_;
  std::string joint_name_;
  LuGreParams p_;
};

/// An ordered set of force elements; their states are concatenated in order.
class ForceSet {
 public:
  ForceSet() = default;
  void add(ForceElementPtr e);
  int num_states() const { return nz_; }
  const std::vector<ForceElementPtr>& elements() const { return elements_; }
  std::vector<std::string> state_names() const;
  /// Q = Σ elements (Q is overwritten), zdot for all states; dQ_dqd overwritten when given.
  void evaluate(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double* z, Eigen::VectorXd& Q,
                double* zdot, Eigen::MatrixXd* dQ_dqd = nullptr) const;
  /// evaluate() over dual numbers (ForceElement::apply_dual): Q (nq entries) is overwritten.
  void evaluate_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* z,
                     int nq, JacobianScalar* Q, JacobianScalar* zdot) const;
  /// Generalized force of element k alone (allocates; for reporting).
  Eigen::VectorXd element_force(int k, double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                const double* z) const;
  /// The same into Q, with zdot as the element's state-rate workspace (no allocation once sized).
  void element_force(int k, double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double* z,
                     Eigen::VectorXd& Q, std::vector<double>& zdot) const;
  int state_offset(int k) const { return offsets_[k]; }
 private:
  std::vector<ForceElementPtr> elements_;
  std::vector<int> offsets_;
  int nz_ = 0;
};

}  // namespace refdyn
