#pragma once
/// A constraint kind written once, over a scalar S (as Ceres' AutoDiffCostFunction writes a
/// residual once as `template <typename T> operator()`, and Drake's systems are `<T>`):
///
///     class MyKind final : public ConstraintLaw<MyKind> {
///      public:
///       template <class S> void law(const LawInput<S>& in, LawRows<S>& out) const;
///       …  // rows(), first_order(), rheonomic(), points(), describe(), symbolic()
///     };
///
/// law<S> writes the kind's rows — Φ (or c), Φ̇, A and γ in the conventions of constraints.hpp —
/// from the kinematic quantities of `in` (time, q, q̇ and the declared points' PointState) with
/// the operations of namespace `law_ops` below. ConstraintLaw derives both evaluations from it:
///   evaluate()       = law<double>          (Eigen's products on PointState: the arithmetic the
///                                            double results have always had, bit for bit)
///   evaluate_dual()  = law<JacobianScalar>  (exact derivatives along the seeds of t, q and q̇;
///                                            the value parts are law<double>'s to rounding)
///   symbolic()       = law<Formula>         (the rows' texts for `refdyn generate`: formula.hpp;
///                                            the kind's scenario numbers enter as param<S>(n),
///                                            which keeps their names in the text)
/// and reports exact_derivatives() = true, so build_problem accepts the kind under method: bdf
/// and beside jerk rows. tests/law_test.cpp evaluates every kind's text against its law. A kind
/// whose law<S> cannot run over Formulas (the expression constraint: its law is its compiled
/// tape, its text the scenario's) declares `static constexpr bool kOwnSymbolicForm = true` and
/// overrides symbolic().
///
/// Sizes: q, q̇ have n = model.nv entries; A's row i has n entries; out.phi/phid/gamma rows().
#include "refdyn/constraints/constraints.hpp"

#include <algorithm>
#include <limits>
#include <optional>
#include <type_traits>

namespace refdyn {

/// The generic multibody arrays (linear3.hpp: lift, zero3) over Formulas, for law<Formula>.
template <>
struct multibody::ScalarTraits<Formula> {
  static Formula from_double(double v) { return Formula(v); }
  static Formula sin(const Formula& x) { return refdyn::sin(x); }
  static Formula cos(const Formula& x) { return refdyn::cos(x); }
  static Formula sqrt(const Formula& x) { return refdyn::sqrt(x); }
  static bool is_zero(const Formula& x) { return x.is_zero(); }
};

/// What law<S> reads: ConstraintInput (S = double) or ConstraintInputDual (S = JacobianScalar).
template <class S> struct LawTypes;
template <> struct LawTypes<double> {
  using Input = ConstraintInput;
  using Point = PointState;
  using Vec = Vec3;
  using SurfaceValue = ImplicitSurface::Value;
};
template <> struct LawTypes<JacobianScalar> {
  using Input = ConstraintInputDual;
  using Point = PointStateT<JacobianScalar>;
  using Vec = multibody::Vec3T<JacobianScalar>;
  using SurfaceValue = ImplicitSurface::ValueDual;
};
template <class S> using LawInput = typename LawTypes<S>::Input;
template <class S> using LawVec3 = typename LawTypes<S>::Vec;

/// What law<Formula> reads (law_detail::formula_inputs): t, q(j), qd(j) and the declared points' x(P),
/// vx(P), R11(P)… as variables of the expression language.
struct ConstraintInputFormula {
  Formula t;
  int n;
  const Formula* q;
  const Formula* qd;
  const std::vector<PointStateT<Formula>>& points;
  Formula* scratch = nullptr;
};
template <> struct LawTypes<Formula> {
  using Input = ConstraintInputFormula;
  using Point = PointStateT<Formula>;
  using Vec = multibody::Vec3T<Formula>;
  using SurfaceValue = ImplicitSurface::ValueFormula;
};

/// What law<S> writes: phi, phid, gamma by row (out.phi[i] = …) and A through the functions
/// below, which are, for S = double, the Eigen expressions the kinds were written with.
template <class S> struct LawRows;

/// For law<Formula>: the rows' Φ (or c) texts; Φ̇, γ and A, which the generator derives from Φ
/// itself, are written and dropped.
template <>
struct LawRows<Formula> {
  std::vector<Formula> phi, phid, gamma;
  explicit LawRows(int rows) : phi(rows), phid(rows), gamma(rows) {}
  template <class... Args> void A_dot(Args&&...) {}
  template <class... Args> void A_dot_diff(Args&&...) {}
  template <class... Args> void A_axis(Args&&...) {}
  template <class... Args> void A_axis_diff(Args&&...) {}
  template <class... Args> void A_add_axis(Args&&...) {}
  template <class... Args> void A_zero(Args&&...) {}
  template <class... Args> void A_set(Args&&...) {}
  template <class... Args> void A_add(Args&&...) {}
};

template <>
struct LawRows<double> {
  using Matrix3X = Eigen::Matrix<double, 3, Eigen::Dynamic>;
  Eigen::Ref<Eigen::VectorXd> phi, phid, gamma;
  Eigen::Ref<Eigen::MatrixXd> A;
  /// A(i, :) = uᵀ C
  void A_dot(int i, const Vec3& u, const Matrix3X& C) { A.row(i).noalias() = u.transpose().lazyProduct(C); }
  /// A(i, :) = uᵀ (C1 − C2)
  void A_dot_diff(int i, const Vec3& u, const Matrix3X& C1, const Matrix3X& C2) {
    A.row(i).noalias() = u.transpose().lazyProduct(C1 - C2);
  }
  /// A(i, :) = C(k, :)
  void A_axis(int i, const Matrix3X& C, int k) { A.row(i) = C.row(k); }
  /// A(i, :) = C1(k, :) − C2(k, :)
  void A_axis_diff(int i, const Matrix3X& C1, const Matrix3X& C2, int k) { A.row(i) = C1.row(k) - C2.row(k); }
  /// A(i, :) += s C(k, :)
  void A_add_axis(int i, double s, const Matrix3X& C, int k) { A.row(i) += s * C.row(k); }
  void A_zero(int i) { A.row(i).setZero(); }
  void A_set(int i, int j, double v) { A(i, j) = v; }
  void A_add(int i, int j, double v) { A(i, j) += v; }
};

template <>
struct LawRows<JacobianScalar> {
  using S = JacobianScalar;
  using Columns = std::vector<multibody::Vec3T<S>>;
  S* phi;
  S* phid;
  S* gamma;
  S* A;  ///< rows() × n, row-major
  int n;
  void A_dot(int i, const multibody::Vec3T<S>& u, const Columns& C) {
    for (int j = 0; j < n; ++j) A[i * n + j] = multibody::dot(u, C[j]);
  }
  void A_dot_diff(int i, const multibody::Vec3T<S>& u, const Columns& C1, const Columns& C2) {
    for (int j = 0; j < n; ++j) A[i * n + j] = multibody::dot(u, multibody::sub(C1[j], C2[j]));
  }
  void A_axis(int i, const Columns& C, int k) {
    for (int j = 0; j < n; ++j) A[i * n + j] = C[j][k];
  }
  void A_axis_diff(int i, const Columns& C1, const Columns& C2, int k) {
    for (int j = 0; j < n; ++j) A[i * n + j] = C1[j][k] - C2[j][k];
  }
  void A_add_axis(int i, const S& s, const Columns& C, int k) {
    for (int j = 0; j < n; ++j) A[i * n + j] += s * C[j][k];
  }
  void A_zero(int i) { std::fill_n(A + i * n, n, S(0.0)); }
  void A_set(int i, int j, const S& v) { A[i * n + j] = v; }
  void A_add(int i, int j, const S& v) { A[i * n + j] += v; }
};

/// The operations a law is written with, for both point representations: Eigen's (double, the
/// expressions of the original kinds) and linear3.hpp's arrays (dual numbers).
namespace law_ops {

using multibody::cross;
using multibody::dot;
using multibody::mul;
using multibody::scale;
using multibody::sub;

inline double dot(const Vec3& a, const Vec3& b) { return a.dot(b); }
inline Vec3 sub(const Vec3& a, const Vec3& b) { return a - b; }
inline Vec3 cross(const Vec3& a, const Vec3& b) { return a.cross(b); }
inline Vec3 mul(const Mat3& R, const Vec3& v) { return R * v; }
inline Vec3 scale(const Vec3& a, double s) { return a * s; }
inline Vec3 div(const Vec3& a, double s) { return a / s; }
template <class S> multibody::Vec3T<S> div(const multibody::Vec3T<S>& a, const S& s) {
  return {a[0] / s, a[1] / s, a[2] / s};
}
inline double squared_norm(const Vec3& a) { return a.squaredNorm(); }
template <class S> S squared_norm(const multibody::Vec3T<S>& a) { return multibody::dot(a, a); }
inline double norm(const Vec3& a) { return a.norm(); }
template <int N> ad::Dual<N> norm(const multibody::Vec3T<ad::Dual<N>>& a) { return ad::sqrt(multibody::dot(a, a)); }
inline Formula norm(const multibody::Vec3T<Formula>& a) { return sqrt(multibody::dot(a, a)); }

/// A constant vector as the law's vector type: the Vec3 itself for double (no copy), its
/// entries lifted for a dual number.
template <class S> decltype(auto) constant3(const Vec3& v) {
  if constexpr (std::is_same_v<S, double>) return (v);
  else return multibody::lift<S>(v);
}
/// The same with the scenario's texts of its entries (param<S>): the values for double and the
/// dual numbers, the texts for a Formula.
template <class S> decltype(auto) constant3(const Vec3& v, const Number3& texts) {
  if constexpr (std::is_same_v<S, Formula>) return multibody::Vec3T<Formula>{param<S>(texts[0]), param<S>(texts[1]), param<S>(texts[2])};
  else return constant3<S>(v);
}
/// (a, b, c) as the law's vector type.
inline Vec3 vec3(double a, double b, double c) { return Vec3(a, b, c); }
template <int N> multibody::Vec3T<ad::Dual<N>> vec3(const ad::Dual<N>& a, const ad::Dual<N>& b, const ad::Dual<N>& c) {
  return {a, b, c};
}
inline multibody::Vec3T<Formula> vec3(const Formula& a, const Formula& b, const Formula& c) { return {a, b, c}; }
/// M(r, c) = v for Eigen's Mat3 and linear3.hpp's row-major Mat3T.
inline void set_entry(Mat3& M, int r, int c, double v) { M(r, c) = v; }
template <class S> void set_entry(multibody::Mat3T<S>& M, int r, int c, const S& v) { M[3 * r + c] = v; }
/// s I
inline Mat3 scaled_identity(double s) { return s * Mat3::Identity(); }
template <class S> multibody::Mat3T<S> scaled_identity(const S& s) {
  return multibody::scale(multibody::identity3<S>(), s);
}

/// The surface's value at (r, t): eval() for double, eval_dual() for dual numbers.
inline ImplicitSurface::Value surface_value(const ImplicitSurface& f, const Vec3& r, double t) { return f.eval(r, t); }
inline ImplicitSurface::ValueDual surface_value(const ImplicitSurface& f, const multibody::Vec3T<JacobianScalar>& r,
                                                const JacobianScalar& t) {
  return f.eval_dual(r, t);
}

/// The surface's text at (x(P), y(P), z(P), t) (eval_formula); throws NoSymbolicForm for a
/// surface without one.
inline ImplicitSurface::ValueFormula surface_value(const ImplicitSurface& f, const multibody::Vec3T<Formula>& r,
                                                  const Formula& t) {
  std::optional<ImplicitSurface::ValueFormula> v = f.eval_formula(r, t);
  if (!v) throw NoSymbolicForm{"the surface " + f.describe() + " has no symbolic form"};
  return *v;
}

/// −x; for a dual number its derivative parts are 0 − x.d (never −0), so that an unseeded time
/// gives the bits of the constant −x.v.
inline double neg(double x) { return -x; }
inline Formula neg(const Formula& x) { return -x; }
template <int N> ad::Dual<N> neg(const ad::Dual<N>& x) {
  ad::Dual<N> r(-x.v);
  for (int k = 0; k < N; ++k) r.d[k] = 0.0 - x.d[k];
  return r;
}
/// The value part.
inline double value_of(double x) { return x; }
template <int N> double value_of(const ad::Dual<N>& x) { return x.v; }
inline double value_of(const Formula&) { return std::numeric_limits<double>::quiet_NaN(); }  // a text has no value
/// True where a term with this factor may be skipped: a double zero adds nothing (the double
/// path's shortcut); a dual number's zero value may carry non-zero derivative parts, so never.
inline bool skippable(double x) { return x == 0; }
template <int N> bool skippable(const ad::Dual<N>&) { return false; }
inline bool skippable(const Formula& x) { return x.is_zero(); }
/// !(x > bound): a guard against a value near a singularity (it also holds for NaN). A Formula
/// has no value, and its text is the formula everywhere: never.
inline bool not_above(double x, double bound) { return !(x > bound); }
template <int N> bool not_above(const ad::Dual<N>& x, double bound) { return !(x.v > bound); }
inline bool not_above(const Formula&, double) { return false; }

}  // namespace law_ops

namespace law_detail {
/// law<Formula>'s inputs over the model's names: t, q(j), qd(j) and, for each declared point P,
/// x(P), vx(P) and R11(P)…; the quantities the symbolic form has no variable for (drift, ω,
/// Jacobians) are a marker that must not reach a row (formula_form checks).
struct FormulaInputs {
  Formula t;
  std::vector<Formula> q, qd;
  std::vector<PointStateT<Formula>> points;
  ConstraintInputFormula input() const {
    return {t, static_cast<int>(q.size()), q.data(), qd.data(), points, nullptr};
  }
};
FormulaInputs formula_inputs(const Model& model, const std::vector<int>& points);
/// The symbolic form of the rows law<Formula> wrote and of what the scope recorded; Error naming
/// `kind` if a row used a quantity without a variable.
SymbolicForm formula_form(const std::vector<Formula>& rows, const FormulaScope& scope, const std::string& kind);
template <class Kind>
constexpr bool own_symbolic_form() {
  if constexpr (requires { Kind::kOwnSymbolicForm; }) return Kind::kOwnSymbolicForm;
  else return false;
}
}  // namespace law_detail

/// The evaluations of a kind written as law<S> (see the header comment).
template <class Kind>
class ConstraintLaw : public Constraint {
 public:
  std::optional<SymbolicForm> symbolic(const Model& model) const override {
    if constexpr (law_detail::own_symbolic_form<Kind>()) {
      return std::nullopt;
    } else {
      const law_detail::FormulaInputs in = law_detail::formula_inputs(model, this->points());
      FormulaScope scope;
      LawRows<Formula> out(this->rows());
      try {
        static_cast<const Kind&>(*this).template law<Formula>(in.input(), out);
      } catch (const NoSymbolicForm&) {
        return std::nullopt;
      }
      return law_detail::formula_form(out.phi, scope, "constraint '" + this->name + "' (" + this->describe() + ")");
    }
  }
  void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi, Eigen::Ref<Eigen::VectorXd> phid,
                Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> gamma) const final {
    LawRows<double> out{phi, phid, gamma, A};
    static_cast<const Kind&>(*this).template law<double>(in, out);
  }
  void evaluate_dual(const ConstraintInputDual& in, JacobianScalar* phi, JacobianScalar* phid, JacobianScalar* A,
                     JacobianScalar* gamma) const final {
    LawRows<JacobianScalar> out{phi, phid, gamma, A, in.n};
    static_cast<const Kind&>(*this).template law<JacobianScalar>(in, out);
  }
  bool exact_derivatives() const override { return true; }
};

/// An implicit surface written once as
///     template <class S> void law(const LawVec3<S>& r, const S& t, typename LawTypes<S>::SurfaceValue& v) const;
/// (v arrives zeroed): eval() is law<double>, eval_dual() law<JacobianScalar>.
template <class Surface>
class SurfaceLaw : public ImplicitSurface {
 public:
  Value eval(const Vec3& r, double t) const final {
    Value v;
    static_cast<const Surface&>(*this).template law<double>(r, t, v);
    return v;
  }
  ValueDual eval_dual(const multibody::Vec3T<JacobianScalar>& r, const JacobianScalar& t) const final {
    ValueDual v;
    v.f = v.ft = v.ftt = JacobianScalar(0.0);
    v.grad = v.grad_t = multibody::zero3<JacobianScalar>();
    v.hess = multibody::zero33<JacobianScalar>();
    static_cast<const Surface&>(*this).template law<JacobianScalar>(r, t, v);
    return v;
  }
  std::optional<ValueFormula> eval_formula(const multibody::Vec3T<Formula>& r, const Formula& t) const final {
    ValueFormula v;
    v.grad = v.grad_t = multibody::zero3<Formula>();
    v.hess = multibody::zero33<Formula>();
    static_cast<const Surface&>(*this).template law<Formula>(r, t, v);
    return v;
  }
  bool exact_derivatives() const final { return true; }
};

}  // namespace refdyn
