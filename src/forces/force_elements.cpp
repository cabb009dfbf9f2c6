#include "refdyn/forces/force_elements.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"

#include <cmath>

namespace refdyn {

namespace {

void need(bool ok, const std::string& what, const std::string& expected, double got) {
  if (!ok) throw Error(expected_got(what, expected, fmt(got)));
}

class JointDamping final : public ForceElement {
 public:
  JointDamping(int j, std::string n, Number b) : j_(j), n_(std::move(n)), b_(std::move(b)) {}
  std::string name() const override { return "damping(" + n_ + ")"; }
  void apply(double, const Eigen::VectorXd&, const Eigen::VectorXd& qd, const double*, Eigen::VectorXd& Q,
             double*, Eigen::MatrixXd* dQ) const override {
    Q[j_] -= b_ * qd[j_];
    if (dQ) (*dQ)(j_, j_) -= b_;
  }
  void apply_dual(double, const JacobianScalar*, const JacobianScalar* qd, const JacobianScalar*, JacobianScalar* Q,
                  JacobianScalar*) const override {
    Q[j_] -= b_.value * qd[j_];
  }
  std::optional<SymbolicForm> symbolic() const override {
    SymbolicForm f;
    f.rows = {"-" + symbolic_number(b_) + "*qd(" + n_ + ")"};
    f.scenario_texts = any_text(b_);
    f.joints = {j_};
    return f;
  }
  bool add_rate(double, const Eigen::VectorXd&, const Eigen::VectorXd&, const Eigen::VectorXd& qdd,
                Eigen::VectorXd& Qdot) const override {
    Qdot[j_] -= b_ * qdd[j_];
    return true;
  }
 private:
  int j_;
  std::string n_;
  Number b_;
};

class JointSpring final : public ForceElement {
 public:
  JointSpring(int j, std::string n, Number k, Number r) : j_(j), n_(std::move(n)), k_(std::move(k)), r_(std::move(r)) {}
  std::string name() const override { return "spring(" + n_ + ")"; }
  void apply(double, const Eigen::VectorXd& q, const Eigen::VectorXd&, const double*, Eigen::VectorXd& Q, double*,
             Eigen::MatrixXd*) const override {
    Q[j_] -= k_ * (q[j_] - r_);
  }
  void apply_dual(double, const JacobianScalar* q, const JacobianScalar*, const JacobianScalar*, JacobianScalar* Q,
                  JacobianScalar*) const override {
    Q[j_] -= k_.value * (q[j_] - r_.value);
  }
  std::optional<SymbolicForm> symbolic() const override {
    SymbolicForm f;
    f.rows = {"-" + symbolic_number(k_) + "*(q(" + n_ + ") - " + symbolic_number(r_) + ")"};
    f.scenario_texts = any_text(k_, r_);
    f.joints = {j_};
    return f;
  }
  bool add_rate(double, const Eigen::VectorXd&, const Eigen::VectorXd& qd, const Eigen::VectorXd&,
                Eigen::VectorXd& Qdot) const override {
    Qdot[j_] -= k_ * qd[j_];
    return true;
  }
 private:
  int j_;
  std::string n_;
  Number k_, r_;
};

class JointEffort final : public ForceElement {
 public:
  JointEffort(int j, std::string n, TimeFunctionPtr f) : j_(j), n_(std::move(n)), f_(std::move(f)) {}
  std::string name() const override { return "effort(" + n_ + ")"; }
  bool actuator() const override { return true; }
  void apply(double t, const Eigen::VectorXd&, const Eigen::VectorXd&, const double*, Eigen::VectorXd& Q, double*,
             Eigen::MatrixXd*) const override {
    Q[j_] += f_->eval(t).f;
  }
  void apply_dual(double t, const JacobianScalar*, const JacobianScalar*, const JacobianScalar*, JacobianScalar* Q,
                  JacobianScalar*) const override {
    Q[j_] += f_->eval(t).f;
  }
  std::optional<SymbolicForm> symbolic() const override {
    std::optional<SymbolicForm> f = f_->symbolic();
    if (!f) return std::nullopt;
    f->functions = {{"effort", f->rows[0]}};
    f->rows = {"effort"};
    f->joints = {j_};
    return f;
  }
  bool add_rate(double t, const Eigen::VectorXd&, const Eigen::VectorXd&, const Eigen::VectorXd&,
                Eigen::VectorXd& Qdot) const override {
    Qdot[j_] += f_->eval(t).df;
    return true;
  }
 private:
  int j_;
  std::string n_;
  TimeFunctionPtr f_;
};

}  // namespace

NewForceElement joint_damping(const Model& model, const std::string& joint, Number b) {
  need(std::isfinite(b.value) && b >= 0, "damping coefficient of joint '" + joint + "'", "a finite value >= 0", b);
  return std::make_shared<JointDamping>(model.joint_index(joint), joint, b);
}
NewForceElement joint_spring(const Model& model, const std::string& joint, Number k, Number q_rest) {
  need(std::isfinite(k.value) && k >= 0, "spring stiffness of joint '" + joint + "'", "a finite value >= 0", k);
  need(std::isfinite(q_rest.value), "spring rest position of joint '" + joint + "'", "a finite value", q_rest);
  return std::make_shared<JointSpring>(model.joint_index(joint), joint, k, q_rest);
}
NewForceElement joint_effort(const Model& model, const std::string& joint, TimeFunctionPtr f) {
  if (!f) throw Error("joint_effort: expected a time function, got none");
  return std::make_shared<JointEffort>(model.joint_index(joint), joint, std::move(f));
}

FlexibleDrive::FlexibleDrive(const Model& model, const std::string& joint, FlexibleDriveParams p,
                             TimeFunctionPtr profile)
    : j_(model.joint_index(joint)), joint_name_(joint), p_(p), profile_(std::move(profile)) {
  need(std::isfinite(p.stiffness.value) && p.stiffness >= 0, "flexible drive stiffness", "a finite value >= 0", p.stiffness);
  need(std::isfinite(p.damping.value) && p.damping >= 0, "flexible drive damping", "a finite value >= 0", p.damping);
  if (!profile_) throw Error("flexible drive: expected a displacement profile, got none");
}

std::vector<std::string> FlexibleDrive::signal_names() const {
  const std::string suffix = label.empty() ? "" : "_" + label;
  return {"psi_dr" + suffix, "tau_drive" + suffix};
}

void FlexibleDrive::signals(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double*,
                            double* out) const {
  out[0] = profile_->eval(t).f;
  out[1] = torque(t, q, qd);
}

double FlexibleDrive::torque(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd) const {
  const TimeValue psi = profile_->eval(t);
  return p_.stiffness * (psi.f - q[j_]) + p_.damping * (psi.df - qd[j_]);
}

bool FlexibleDrive::add_rate(double t, const Eigen::VectorXd&, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd,
                            Eigen::VectorXd& Qdot) const {
  const TimeValue psi = profile_->eval(t);
  Qdot[j_] += p_.stiffness * (psi.df - qd[j_]) + p_.damping * (psi.ddf - qdd[j_]);
  return true;
}

void FlexibleDrive::apply(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double*,
                          Eigen::VectorXd& Q, double*, Eigen::MatrixXd* dQ) const {
  Q[j_] += torque(t, q, qd);
  if (dQ) (*dQ)(j_, j_) -= p_.damping;
}

void ForceElement::apply_dual(double, const JacobianScalar*, const JacobianScalar*, const JacobianScalar*,
                              JacobianScalar*, JacobianScalar*) const {
  throw Error("force element '" + name() + "' has no exact derivatives (ForceElement::apply_dual), which implicit "
              "integration needs (hint: use method: rk4 or dopri5, or implement apply_dual for this element)");
}

void FlexibleDrive::apply_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar*,
                               JacobianScalar* Q, JacobianScalar*) const {
  const TimeValue psi = profile_->eval(t);
  Q[j_] += p_.stiffness.value * (psi.f - q[j_]) + p_.damping.value * (psi.df - qd[j_]);
}

LuGreFriction::LuGreFriction(const Model& model, const std::string& joint, LuGreParams p)
    : j_(model.joint_index(joint)), joint_name_(joint), p_(p) {
  const std::string w = "LuGre friction of joint '" + joint + "': ";
  need(std::isfinite(p.mu_s.value) && p.mu_s > 0, w + "mu_s", "a finite value > 0", p.mu_s);
  need(std::isfinite(p.mu_k.value) && p.mu_k > 0, w + "mu_k", "a finite value > 0", p.mu_k);
  need(std::isfinite(p.sigma0.value) && p.sigma0 >= 0, w + "sigma0", "a finite value >= 0", p.sigma0);
  need(std::isfinite(p.sigma1.value) && p.sigma1 >= 0, w + "sigma1", "a finite value >= 0", p.sigma1);
  need(std::isfinite(p.sigma2.value) && p.sigma2 >= 0, w + "sigma2", "a finite value >= 0", p.sigma2);
  need(std::isfinite(p.v_stribeck.value) && p.v_stribeck > 0, w + "Stribeck velocity", "a finite value > 0", p.v_stribeck);
}

std::optional<SymbolicForm> FlexibleDrive::symbolic() const {
  std::optional<SymbolicForm> f = profile_->symbolic();
  if (!f) return std::nullopt;
  f->functions = {{"psi_dr", f->rows[0]}};
  f->rows = {symbolic_number(p_.stiffness) + "*(psi_dr - q(" + joint_name_ + ")) + " + symbolic_number(p_.damping) +
             "*(d_psi_dr - qd(" + joint_name_ + "))"};
  f->scenario_texts = f->scenario_texts || any_text(p_.stiffness, p_.damping);
  f->joints = {j_};
  return f;
}

std::optional<SymbolicForm> LuGreFriction::symbolic() const {
  const std::string v = "qd(" + joint_name_ + ")";
  const std::string g = "(" + symbolic_number(p_.mu_k) + " + (" + symbolic_number(p_.mu_s) + " - " +
                        symbolic_number(p_.mu_k) + ")*exp(-(" + v + "/" + symbolic_number(p_.v_stribeck) + ")^2))";
  SymbolicForm f;
  f.state_rates = {v + " - " + symbolic_number(p_.sigma0) + "*abs(" + v + ")*z(0)/" + g};
  f.rows = {"-(" + symbolic_number(p_.sigma0) + "*z(0) + " + symbolic_number(p_.sigma1) + "*zdot(0) + " +
            symbolic_number(p_.sigma2) + "*" + v + ")"};
  f.scenario_texts = any_text(p_.mu_s, p_.mu_k, p_.sigma0, p_.sigma1, p_.sigma2, p_.v_stribeck);
  f.joints = {j_};
  return f;
}

void LuGreFriction::apply(double, const Eigen::VectorXd&, const Eigen::VectorXd& qd, const double* z,
                          Eigen::VectorXd& Q, double* zdot, Eigen::MatrixXd* dQ) const {
  const double v = qd[j_];
  const double r = v / p_.v_stribeck;
  const double e = std::exp(-r * r);
  const double g = p_.mu_k + (p_.mu_s - p_.mu_k) * e;
  const double av = std::abs(v);
  const double zd = v - p_.sigma0 * av * z[0] / g;
  zdot[0] = zd;
  Q[j_] -= p_.sigma0 * z[0] + p_.sigma1 * zd + p_.sigma2 * v;
  if (dQ) {
    const double sgn = (v > 0) - (v < 0);
    const double dg = (p_.mu_s - p_.mu_k) * e * (-2.0 * v / (p_.v_stribeck * p_.v_stribeck));
    const double dzd = 1.0 - p_.sigma0 * z[0] * (sgn * g - av * dg) / (g * g);
    (*dQ)(j_, j_) -= p_.sigma1 * dzd + p_.sigma2;
  }
}

void LuGreFriction::apply_dual(double, const JacobianScalar*, const JacobianScalar* qd, const JacobianScalar* z,
                               JacobianScalar* Q, JacobianScalar* zdot) const {
  using multibody::abs;
  using multibody::exp;
  const JacobianScalar& v = qd[j_];
  const JacobianScalar r = v / p_.v_stribeck.value;
  const JacobianScalar g = p_.mu_k.value + (p_.mu_s.value - p_.mu_k.value) * exp(-(r * r));
  const JacobianScalar zd = v - p_.sigma0.value * abs(v) * z[0] / g;
  zdot[0] = zd;
  Q[j_] -= p_.sigma0.value * z[0] + p_.sigma1.value * zd + p_.sigma2.value * v;
}

bool LuGreFriction::add_rate_with_states(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                         const Eigen::VectorXd& qdd, const double* z, const double* zdot,
                                         Eigen::VectorXd& Qdot) const {
  // The force depends on (q̇, z) only (no explicit time): its rate is the derivative of
  // apply_dual along the seeds q̇ → q̈, z → ż (one direction).
  const int n = static_cast<int>(q.size());
  std::vector<JacobianScalar> qv(n), qdv(n), Q(n, JacobianScalar(0.0));
  for (int i = 0; i < n; ++i) {
    qv[i] = JacobianScalar::variable(q[i], 0, 0.0);
    qdv[i] = JacobianScalar::variable(qd[i], 0, qdd[i]);
  }
  const JacobianScalar zv = JacobianScalar::variable(z[0], 0, zdot[0]);
  JacobianScalar zd;
  apply_dual(t, qv.data(), qdv.data(), &zv, Q.data(), &zd);
  for (int i = 0; i < n; ++i) Qdot[i] += Q[i].d[0];
  return true;
}

void ForceSet::evaluate_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* z,
                             int nq, JacobianScalar* Q, JacobianScalar* zdot) const {
  for (int i = 0; i < nq; ++i) Q[i] = JacobianScalar(0.0);
  for (size_t k = 0; k < elements_.size(); ++k)
    elements_[k]->apply_dual(t, q, qd, z + offsets_[k], Q, zdot + offsets_[k]);
}

void ForceSet::add(ForceElementPtr e) {
  if (!e) throw Error("ForceSet::add: expected a force element, got none");
  offsets_.push_back(nz_);
  nz_ += e->num_states();
  elements_.push_back(std::move(e));
}

/// The states' column names, distinct: an element's own name (LuGre: z_<joint>) unless another
/// element of the set has a state of that name too (two LuGre elements on one joint); then each
/// of them is suffixed "_<label>" (its scenario `name:`) or, unnamed, "_<k>", its ordinal among
/// the elements sharing the name (z_j2_1, z_j2_2). A set without such duplicates (every scenario
/// before this rule) keeps its names.
std::vector<std::string> ForceSet::state_names() const {
  std::vector<std::string> raw;
  std::vector<const ForceElement*> owner;
  for (const auto& e : elements_)
    for (auto& s : e->state_names()) {
      raw.push_back(s);
      owner.push_back(e.get());
    }
  std::vector<std::string> n = raw;
  for (size_t i = 0; i < raw.size(); ++i) {
    int ordinal = 0, count = 0;
    for (size_t j = 0; j < raw.size(); ++j)
      if (raw[j] == raw[i]) {
        ++count;
        if (j <= i) ++ordinal;
      }
    if (count > 1) n[i] = raw[i] + "_" + (owner[i]->label.empty() ? std::to_string(ordinal) : owner[i]->label);
  }
  return n;
}

void ForceSet::evaluate(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double* z,
                        Eigen::VectorXd& Q, double* zdot, Eigen::MatrixXd* dQ) const {
  Q.setZero();
  if (dQ) dQ->setZero();
  for (size_t k = 0; k < elements_.size(); ++k)
    elements_[k]->apply(t, q, qd, z + offsets_[k], Q, zdot + offsets_[k], dQ);
}

Eigen::VectorXd ForceSet::element_force(int k, double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                        const double* z) const {
  Eigen::VectorXd Q = Eigen::VectorXd::Zero(q.size());
  std::vector<double> zd(std::max(1, elements_[k]->num_states()));
  elements_[k]->apply(t, q, qd, z + offsets_[k], Q, zd.data(), nullptr);
  return Q;
}

}  // namespace refdyn
