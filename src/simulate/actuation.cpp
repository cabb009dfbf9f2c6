// The machine as built for the controllers: partition, motors, N and the efforts (actuation.hpp).
#include "refdyn/simulate/actuation.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/forces/force_elements.hpp"
#include "refdyn/multibody/dual_dynamics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/reference/reference_dynamics.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace refdyn {

Actuation Actuation::full(const Model& model) {
  Actuation a;
  for (int i = 0; i < model.nv; ++i) a.actuated.push_back(i), a.independent.push_back(i);
  return a;
}

std::vector<int> Actuation::assignable() const {
  if (!switching) return independent;
  std::vector<int> all = independent;
  all.insert(all.end(), dependent.begin(), dependent.end());
  std::sort(all.begin(), all.end());
  return all;
}

bool Actuation::is_actuated(int j) const { return std::binary_search(actuated.begin(), actuated.end(), j); }
bool Actuation::is_independent(int j) const { return std::binary_search(independent.begin(), independent.end(), j); }

std::string Actuation::names(const Model& model, const std::vector<int>& joints) {
  std::string s;
  for (int j : joints) s += (s.empty() ? "" : ", ") + model.joint_name[j];
  return s.empty() ? "none" : s;
}

namespace {

// Baumgarte right-hand side of one row, as the reference dynamics forms it.
template <class S>
S stabilised_rhs(bool first_order, const S& phi, const S& phid, const S& gamma, const Actuation& a) {
  if (first_order) return -gamma - a.beta_first_order * phi;
  return -gamma - (2.0 * a.alpha) * phid - (a.beta * a.beta) * phi;
}

}  // namespace

template <class S>
struct ActuatedModel<S>::Workspace {
  Workspace(const Model& m, const ConstraintSet* set) : data(m), q(m.nv), qd(m.nv), qdd(m.nv), out(m.nv) {
    if (set && set->rows() > 0) {
      if constexpr (std::is_same_v<S, double>)
        ev.emplace(m, *set);
      else
        evd.emplace(m, *set);
    }
  }
  Data data;
  std::optional<ConstraintEval> ev;
  std::optional<ConstraintEvalDual> evd;
  Eigen::VectorXd q, qd, qdd, out;
  Matrix A, Kdc, rhs_ic, X, P, PPt, Y, ta;
  Vector rhs, r;
  std::vector<int> row_of;
  Eigen::MatrixXd lu;  // double: the elimination's workspace (no allocation after the first call)
};

namespace {
// X = A⁻¹ B for a square A; false when A is singular to working precision. Doubles: Gaussian
// elimination with partial pivoting in the workspace LU, singular when a pivot is below 1e-13 ×
// the largest (no allocation after the first call with these sizes, no calls into a blocked
// kernel: these systems are the plant's m × m and k × k, small); dual numbers: ad::solve_square.
// The elimination on column-major arrays: a (m × m, overwritten by U and the multipliers), x (m ×
// c, overwritten by the solution). M > 0: m = M at compile time (the loops unroll).
template <int M>
bool eliminate(int m, int c, double* __restrict a, double* __restrict x) {
  if constexpr (M > 0) m = M;
  double largest = 0, smallest = std::numeric_limits<double>::infinity();
  for (int j = 0; j < m; ++j) {
    int p = j;
    double best = std::abs(a[j * m + j]);
    for (int i = j + 1; i < m; ++i)
      if (std::abs(a[j * m + i]) > best) best = std::abs(a[j * m + i]), p = i;
    if (!(best > 0)) return false;
    if (p != j) {
      for (int k = 0; k < m; ++k) std::swap(a[k * m + j], a[k * m + p]);
      for (int k = 0; k < c; ++k) std::swap(x[k * m + j], x[k * m + p]);
    }
    largest = std::max(largest, best), smallest = std::min(smallest, best);
    for (int i = j + 1; i < m; ++i) {
      const double f = a[j * m + i] / a[j * m + j];
      for (int k = j + 1; k < m; ++k) a[k * m + i] -= f * a[k * m + j];
      for (int k = 0; k < c; ++k) x[k * m + i] -= f * x[k * m + j];
    }
  }
  if (m > 0 && !(smallest > 1e-13 * largest)) return false;
  for (int j = m - 1; j >= 0; --j)
    for (int k = 0; k < c; ++k) {
      double v = x[k * m + j];
      for (int l = j + 1; l < m; ++l) v -= a[l * m + j] * x[k * m + l];
      x[k * m + j] = v / a[j * m + j];
    }
  return true;
}

bool eliminate_small(int m, int c, double* a, double* x) {
  switch (m) {
    case 1: return eliminate<1>(m, c, a, x);
    case 2: return eliminate<2>(m, c, a, x);
    case 3: return eliminate<3>(m, c, a, x);
    case 4: return eliminate<4>(m, c, a, x);
    default: return eliminate<0>(m, c, a, x);
  }
}

bool solve(Eigen::MatrixXd& LU, const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, Eigen::MatrixXd& X) {
  LU = A;
  X = B;
  return eliminate_small(static_cast<int>(A.rows()), static_cast<int>(B.cols()), LU.data(), X.data());
}
template <int N>
bool solve(Eigen::MatrixXd&, const ad::MatrixX<ad::Dual<N>>& A, const ad::MatrixX<ad::Dual<N>>& B,
           ad::MatrixX<ad::Dual<N>>& X) {
  return ad::solve_square(A, B, X);
}
}  // namespace

template <class S>
ActuatedModel<S>::ActuatedModel(const Model& model, const Actuation& actuation)
    : model_(model), act_(actuation), ws_(std::make_shared<Workspace>(model, actuation.material.get())),
      ind_(actuation.independent), dep_(actuation.dependent) {}

namespace {
// κ = ‖A‖₁ ‖K_dc⁻¹‖₁ of the values (the reference dynamics' measure); infinity when singular.
double partition_condition(const Eigen::MatrixXd& A, const std::vector<int>& dep) {
  const int m = static_cast<int>(A.rows());
  Eigen::MatrixXd K(m, m);
  for (int j = 0; j < m; ++j) K.col(j) = A.col(dep[j]);
  Eigen::PartialPivLU<Eigen::MatrixXd> lu(K);
  if (!(lu.rcond() > 1e-13)) return std::numeric_limits<double>::infinity();
  return A.cwiseAbs().colwise().sum().maxCoeff() * lu.inverse().cwiseAbs().colwise().sum().maxCoeff();
}
}  // namespace

template <class S>
void ActuatedModel<S>::choose_partition() {
  // A function of the state alone (the same choice for the values and the dual numbers): the
  // initial partition while its κ ≤ kSwitchCondition, else the best-conditioned set.
  const Eigen::MatrixXd A = ws_->A.unaryExpr([](const S& x) { return ad::value(x); });
  const int n = model_.nv, m = static_cast<int>(A.rows());
  ind_ = act_.independent, dep_ = act_.dependent;
  if (partition_condition(A, dep_) <= Actuation::kSwitchCondition) return;
  double best = std::numeric_limits<double>::infinity();
  std::vector<int> pick(m), chosen;
  for (int j = 0; j < m; ++j) pick[j] = j;
  while (true) {  // every m-subset of the n coordinates, in lexicographic order
    const double c = partition_condition(A, pick);
    if (c < best) best = c, chosen = pick;
    int i = m - 1;
    while (i >= 0 && pick[i] == n - m + i) --i;
    if (i < 0) break;
    ++pick[i];
    for (int j = i + 1; j < m; ++j) pick[j] = pick[j - 1] + 1;
  }
  if (chosen.empty()) return;
  dep_ = chosen;
  ind_.clear();
  for (int i = 0; i < n; ++i)
    if (!std::binary_search(dep_.begin(), dep_.end(), i)) ind_.push_back(i);
}

template <class S>
bool ActuatedModel<S>::set_state(double t, const S* q, const S* qd, const PlantRows* plant) {
  if (!act_.constrained()) return true;
  const ConstraintSet& set = *act_.material;
  Workspace& w = *ws_;
  const int n = model_.nv, m = set.rows();
  w.rhs.resize(m);
  if constexpr (std::is_same_v<S, double>) {
    const ConstraintEval* rows = plant ? plant->rows : nullptr;
    if (!rows) {
      w.q = Eigen::Map<const Eigen::VectorXd>(q, n);
      w.qd = Eigen::Map<const Eigen::VectorXd>(qd, n);
      evaluate_constraints(model_, w.data, set, *w.ev, t, w.q, w.qd);
      rows = &*w.ev;
    }
    for (int r = 0; r < m; ++r)
      w.rhs[r] = stabilised_rhs<double>(set.row_first_order(r), rows->phi[r], rows->phid[r], rows->gamma[r], act_);
    if (act_.switching) {
      w.A = rows->A;
      choose_partition();
    }
    if (plant && plant->G && *plant->independent == ind_ && *plant->dependent == dep_) {  // the plant's factorization
      Nd_ = *plant->G;
      qdd_p_.resize(m);
      const Eigen::MatrixXd& Ki = *plant->Kinv;
      for (int i = 0; i < m; ++i) {
        double v = 0;
        for (int j = 0; j < m; ++j) v += Ki(i, j) * w.rhs[j];
        qdd_p_[i] = v;
      }
      return true;
    }
    return factor(rows->A);
  } else {
    (void)plant;
    w.A.resize(m, n);
    evaluate_constraints_dual(model_, set, *w.evd, S(t), q, qd);
    for (int r = 0; r < m; ++r) {
      for (int c = 0; c < n; ++c) w.A(r, c) = w.evd->A[r * n + c];
      w.rhs[r] = stabilised_rhs<S>(set.row_first_order(r), w.evd->phi[r], w.evd->phid[r], w.evd->gamma[r], act_);
    }
  }
  if (act_.switching) choose_partition();
  return factor(w.A);
}

// K_dc [X_ic, x_p] = [K_ic, rhs] for A's columns: N_d = −X_ic, q̈_p = x_p.
template <class S>
bool ActuatedModel<S>::factor(const Matrix& A) {
  Workspace& w = *ws_;
  const int m = static_cast<int>(A.rows()), k = static_cast<int>(ind_.size());
  w.Kdc.resize(m, m);
  w.rhs_ic.resize(m, k + 1);
  for (int j = 0; j < m; ++j) w.Kdc.col(j) = A.col(dep_[j]);
  for (int i = 0; i < k; ++i) w.rhs_ic.col(i) = A.col(ind_[i]);
  w.rhs_ic.col(k) = w.rhs;
  if constexpr (std::is_same_v<S, double>) {  // in place: K_dc becomes its LU, [K_ic, rhs] the solution
    if (!eliminate_small(m, k + 1, w.Kdc.data(), w.rhs_ic.data())) return false;
    Nd_ = -w.rhs_ic.leftCols(k);
    qdd_p_ = w.rhs_ic.col(k);
  } else {
    if (!solve(w.lu, w.Kdc, w.rhs_ic, w.X)) return false;
    Nd_ = -w.X.leftCols(k);
    qdd_p_ = w.X.col(k);
  }
  return true;
}

template <class S>
void ActuatedModel<S>::accelerations(const Vector& u, Vector& qdd) const {
  qdd.resize(model_.nv);
  for (size_t i = 0; i < ind_.size(); ++i) qdd[ind_[i]] = u[i];
  if (!act_.constrained()) return;
  const int k = static_cast<int>(ind_.size());
  for (size_t j = 0; j < dep_.size(); ++j) {  // q̈_dep = q̈_p + N_d u (loops: these are a few rows)
    S v = qdd_p_[static_cast<Eigen::Index>(j)];
    for (int i = 0; i < k; ++i) v += Nd_(static_cast<Eigen::Index>(j), i) * u[i];
    qdd[dep_[j]] = v;
  }
}

template <class S>
bool ActuatedModel<S>::efforts(const Vector& b, Vector& tau) const {
  const int k = static_cast<int>(ind_.size()), na = static_cast<int>(act_.actuated.size());
  if (na < k) return false;
  // r = Nᵀ b and P = Nᵀ S (column a: row act[a] of N, transposed).
  Workspace& w = *ws_;
  Vector& r = w.r;
  r.resize(k);
  for (int i = 0; i < k; ++i) r[i] = b[ind_[i]];
  if (act_.constrained())
    for (size_t j = 0; j < dep_.size(); ++j) r += Nd_.row(j).transpose() * b[dep_[j]];
  if (act_.actuated == ind_) {  // the motors are the assigned coordinates: P = I, τ_a = Nᵀ b
    tau.setZero(model_.nv);
    for (int a = 0; a < na; ++a) tau[act_.actuated[a]] = r[a];
    return true;
  }
  Matrix& P = w.P;
  P.setZero(k, na);
  std::vector<int>& row_of = w.row_of;  // joint -> its place among independent (≥ 0) or dependent (−2 − j)
  row_of.assign(model_.nv, -1);
  for (int i = 0; i < k; ++i) row_of[ind_[i]] = i;
  for (size_t j = 0; j < dep_.size(); ++j) row_of[dep_[j]] = -2 - static_cast<int>(j);
  for (int a = 0; a < na; ++a) {
    const int p = row_of[act_.actuated[a]];
    if (p >= 0)
      P(p, a) = S(1.0);
    else
      P.col(a) = Nd_.row(-2 - p).transpose();
  }
  Matrix& ta = w.ta;
  w.Y = r;  // as a one-column matrix
  if (na == k) {
    if (!solve(w.lu, P, w.Y, ta)) return false;
  } else {
    w.PPt.noalias() = P * P.transpose();
    if (!solve(w.lu, w.PPt, w.Y, w.X)) return false;
    ta.noalias() = P.transpose() * w.X;
  }
  tau.setZero(model_.nv);
  for (int a = 0; a < na; ++a) tau[act_.actuated[a]] = ta(a, 0);
  return true;
}

template <class S>
void ActuatedModel<S>::inverse_dynamics(const S* q, const S* qd, const S* qdd, S* out, const Data* dynamics) {
  const int n = model_.nv;
  if constexpr (std::is_same_v<S, double>) {
    if (dynamics && qd && qdd) {
      Eigen::Map<Eigen::VectorXd> b(out, n);
      b.noalias() = dynamics->M.lazyProduct(Eigen::Map<const Eigen::VectorXd>(qdd, n));
      b += dynamics->nle;
      return;
    }
    Workspace& w = *ws_;
    w.q = Eigen::Map<const Eigen::VectorXd>(q, n);
    if (qd) w.qd = Eigen::Map<const Eigen::VectorXd>(qd, n);
    if (qdd) w.qdd = Eigen::Map<const Eigen::VectorXd>(qdd, n);
    unchecked::rnea(model_, w.data, w.q, qd ? &w.qd : nullptr, qdd ? &w.qdd : nullptr, true, w.out);
    Eigen::Map<Eigen::VectorXd>(out, n) = w.out;
  } else {
    (void)dynamics;
    inverse_dynamics_dual(model_, q, qd, qdd, true, out);
  }
}

template <class S>
void ActuatedModel<S>::computed_torque(const S* q, const S* qd, const Vector& u, const Data* dynamics, S* tau) {
  const int n = model_.nv;
  if constexpr (std::is_same_v<S, double>) {
    Eigen::Map<Eigen::VectorXd> t(tau, n);
    if (dynamics) {
      t.noalias() = dynamics->M.lazyProduct(u);
      t += dynamics->nle;
      return;
    }
    Workspace& w = *ws_;
    w.q = Eigen::Map<const Eigen::VectorXd>(q, n);
    w.qd = Eigen::Map<const Eigen::VectorXd>(qd, n);
    unchecked::mass_matrix_and_bias(model_, w.data, w.q, w.qd);
    t.noalias() = w.data.M.lazyProduct(u);
    t += w.data.nle;
  } else {
    inverse_dynamics_dual(model_, q, qd, u.data(), true, tau);
  }
}

template <class S>
const typename ActuatedModel<S>::Vector& ActuatedModel<S>::gravity(const S* q) {
  const int n = model_.nv;
  if (g_.size() != n) g_.resize(n);
  if constexpr (std::is_same_v<S, double>) {
    Workspace& w = *ws_;
    w.q = Eigen::Map<const Eigen::VectorXd>(q, n);
    unchecked::rnea(model_, w.data, w.q, nullptr, nullptr, true, w.data.g);
    g_ = w.data.g;
  } else {
    inverse_dynamics_dual(model_, q, nullptr, nullptr, true, g_.data());
  }
  return g_;
}

template class ActuatedModel<double>;
template class ActuatedModel<JacobianScalar>;

Actuation make_actuation(const Model& model, std::shared_ptr<const ConstraintSet> material, std::vector<int> actuated,
                         double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, double alpha, double beta,
                         double beta_first_order, double max_condition) {
  Actuation a;
  std::sort(actuated.begin(), actuated.end());
  a.actuated = std::move(actuated);
  a.alpha = alpha, a.beta = beta, a.beta_first_order = beta_first_order;
  const int n = model.nv;
  const int m = material ? material->rows() : 0;
  const int k = n - m;
  if (m > 0) a.material = material;
  auto complement = [n](const std::vector<int>& s) {
    std::vector<int> c;
    for (int i = 0; i < n; ++i)
      if (!std::binary_search(s.begin(), s.end(), i)) c.push_back(i);
    return c;
  };
  if (m == 0) {
    a.independent = complement({});
  } else {
    if (m >= n)
      throw Error("the material constraints have " + std::to_string(m) + " rows for " + std::to_string(n) +
                  " coordinates: the plant cannot move (no coordinate is left for the motors to assign)");
    // The motors as the independent coordinates, when they form a well-conditioned partition.
    bool chosen = false;
    if (static_cast<int>(a.actuated.size()) == k) {
      Data data(model);
      ConstraintEval ev(model, *material);
      evaluate_constraints(model, data, *material, ev, t, q, qd);
      const std::vector<int> dep = complement(a.actuated);
      Eigen::MatrixXd Kdc(m, m);
      for (int j = 0; j < m; ++j) Kdc.col(j) = ev.A.col(dep[j]);
      Eigen::PartialPivLU<Eigen::MatrixXd> lu(Kdc);
      const double cond = ev.A.cwiseAbs().colwise().sum().maxCoeff() *
                          lu.inverse().cwiseAbs().colwise().sum().maxCoeff();
      if (std::isfinite(cond) && cond <= max_condition && lu.rcond() > 1e-13) {
        a.independent = a.actuated;
        chosen = true;
      }
    }
    if (!chosen) {
      ForceSet none;
      ReferenceDynamicsOptions o;
      o.solver = ReferenceSolver::Projection;
      o.max_condition = max_condition;
      ReferenceDynamics rd(model, none, *material, o);
      rd.choose_partition(t, q, qd);
      a.independent = rd.independent();
      std::sort(a.independent.begin(), a.independent.end());
      a.switching = true;
    }
  }
  a.dependent = complement(a.independent);
  const int na = static_cast<int>(a.actuated.size());
  if (na < k)
    throw Error("the plant has " + std::to_string(k) + " coordinate" + (k == 1 ? "" : "s") +
                " for the motors to assign (" + Actuation::names(model, a.independent) +
                (m > 0 ? "; the material constraints fix the others" : "") + ") but " + std::to_string(na) +
                " motor" + (na == 1 ? "" : "s") + " (" + Actuation::names(model, a.actuated) +
                "): list at least " + std::to_string(k) + " joints in actuators");
  ActuatedModel<double> am(model, a);
  if (!am.set_state(t, q.data(), qd.data()))
    throw Error("the material constraints' K_dc is singular at the initial state for the independent coordinates " +
                Actuation::names(model, a.independent));
  // P = Nᵀ S by its action on unit efforts: column a is Nᵀ e_{act[a]}.
  Eigen::MatrixXd P(k, na);
  for (int c = 0; c < na; ++c) {
    Eigen::VectorXd e = Eigen::VectorXd::Zero(n), tau;
    e[a.actuated[c]] = 1.0;
    // Nᵀ e: the efforts routine's r for b = e (independent part plus N_dᵀ e_dep).
    Eigen::VectorXd u = Eigen::VectorXd::Zero(k), col(k);
    for (int i = 0; i < k; ++i) {
      u.setZero();
      u[i] = 1.0;
      Eigen::VectorXd qdd;
      am.accelerations(u, qdd);  // q̈ = q̈_p + N u: column i of N is q̈(e_i) − q̈(0)
      Eigen::VectorXd qdd0;
      am.accelerations(Eigen::VectorXd::Zero(k), qdd0);
      col[i] = (qdd - qdd0).dot(e);
    }
    P.col(c) = col;
  }
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(P, Eigen::ComputeFullU);
  const Eigen::VectorXd sv = svd.singularValues();
  const double tol = 1e-9 * std::max(1.0, sv.size() ? sv[0] : 0.0);
  std::vector<int> unreached;
  for (int i = 0; i < k; ++i)
    if (i >= sv.size() || sv[i] <= tol) {
      int worst = 0;
      svd.matrixU().col(i).cwiseAbs().maxCoeff(&worst);
      unreached.push_back(a.independent[worst]);
    }
  if (!unreached.empty()) {
    std::sort(unreached.begin(), unreached.end());
    unreached.erase(std::unique(unreached.begin(), unreached.end()), unreached.end());
    throw Error("no motor reaches the coordinate" + std::string(unreached.size() == 1 ? " " : "s ") +
                Actuation::names(model, unreached) + " (the motors at " + Actuation::names(model, a.actuated) +
                " cannot produce its acceleration" + (m > 0 ? " through the material constraints" : "") +
                "): add a motor there or at a joint coupled to it");
  }
  return a;
}

}  // namespace refdyn
