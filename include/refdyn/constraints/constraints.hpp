#pragma once
/// Constraints on a model, material or programmed (task-based), in two orders:
///  - holonomic (position) Φ(q, t) = 0, possibly rheonomic:
///        Φ̇ = A q̇ + Φ_t,      Φ̈ = A q̈ + γ,      A = ∂Φ/∂q
///  - first-order (velocity, nonholonomic or programmed speed) c(q, q̇, t) = 0:
///        ċ = A q̈ + γ,        A = ∂c/∂q̇        (c linear in q̇ for the classical B q̇ + s)
///  - acceleration-level (programmed, order p = 2; expression constraints only)
///    B(t, q, q̇) q̈ + s(t, q, q̇) = 0:  A = B, γ = s, Φ = Φ̇ = 0 (no residual at the state level;
///    the reference dynamics writes B q̈ + s there after each solve). See docs/higher_order.md.
/// γ carries every velocity-product and time-derivative term (Φ_tt, ∂Φ_t/∂q q̇ included).
/// Everything is exact: analytic kinematics (C, d of kinematics.hpp) chained with exact
/// derivatives of the task functions.

#include "refdyn/common/dual.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/multibody/dual.hpp"
#include "refdyn/multibody/generic_kinematics.hpp"
#include "refdyn/expression/formula.hpp"
#include "refdyn/expression/time_function.hpp"

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace refdyn {

enum class ConstraintOrigin { Material, Programmed };

/// The order p of a constraint B q^(p) + s = 0 (paper eq. 2.1): 0 position (holonomic),
/// 1 velocity (first order), 2 acceleration. (Jerk, p = 3, is not implemented.)
enum class ConstraintOrder { Position = 0, Velocity = 1, Acceleration = 2 };
const char* to_string(ConstraintOrigin o);
/// "holonomic (position)", "first order (velocity)", "acceleration (order 2)", "jerk (order 3)"
/// for orders 0…3.
const char* order_label(int order);

/// The task geometry a constraint prescribes, recorded when it is built (for the report's plots):
/// a kind ("ellipse": centre cx, cy and half-axes a, b in the x–y plane; "sphere": centre cx, cy,
/// cz and radius r) with its numbers, and the point the constraint holds on it.
struct TaskGeometry {
  std::string kind;
  std::string point;
  std::vector<std::pair<std::string, double>> values;  ///< in the order listed above
  double value(const std::string& name) const;          ///< NaN if absent
};

/// World-frame kinematics of a point, computed once per evaluation and shared by constraints.
struct PointState {
  Vec3 r = Vec3::Zero();         ///< position
  Vec3 v = Vec3::Zero();         ///< velocity C q̇
  Vec3 d = Vec3::Zero();         ///< drift: acceleration − C q̈
  Vec3 w = Vec3::Zero();         ///< angular velocity of the carrying body
  Vec3 wd = Vec3::Zero();        ///< angular-acceleration drift of the carrying body
  Mat3 R = Mat3::Identity();     ///< orientation of the carrying body
  Eigen::Matrix<double, 3, Eigen::Dynamic> C;   ///< ∂r/∂q (3×n)
  Eigen::Matrix<double, 3, Eigen::Dynamic> Jw;  ///< angular Jacobian of the body (3×n)
};

/// What a constraint reads: time, state, the states of the points it declared, and scratch
/// memory of at least scratch_size() doubles owned by the caller's ConstraintEval (so that a
/// constraint object holds no mutable state and one set can be evaluated from several threads,
/// each with its own ConstraintEval).
struct ConstraintInput {
  double t;
  const Eigen::VectorXd& q;
  const Eigen::VectorXd& qd;
  const std::vector<PointState>& points;  ///< indexed by model point index
  double* scratch = nullptr;
};

/// Point kinematics over a scalar S: PointState's quantities (same meanings and conventions,
/// world axes) as arrays of linear3.hpp, for the dual-number evaluation.
template <class S>
struct PointStateT {
  multibody::Vec3T<S> r, v, d, w, wd;   ///< position, velocity, drift (acceleration − C q̈), ω, ω̇ drift
  multibody::Mat3T<S> R;                ///< orientation of the carrying body (row-major)
  std::vector<multibody::Vec3T<S>> C;   ///< n columns of ∂r/∂q
  std::vector<multibody::Vec3T<S>> Jw;  ///< n columns of the angular Jacobian
};

/// What evaluate_dual reads: ConstraintInput over dual numbers (t, q, q̇; q and q̇ n values
/// each) and scratch of at least scratch_size_dual() dual numbers owned by the caller's
/// ConstraintEvalDual. Functions of time enter through t as dual numbers (eval_dual of
/// time_function.hpp, the expressions' variable t), so a seeded t differentiates the rheonomic
/// terms; with an unseeded t (derivative parts 0) they are constants.
struct ConstraintInputDual {
  JacobianScalar t;
  int n;
  const JacobianScalar* q;
  const JacobianScalar* qd;
  const std::vector<PointStateT<JacobianScalar>>& points;  ///< indexed by model point index
  JacobianScalar* scratch = nullptr;
};

class Constraint {
 public:
  virtual ~Constraint() = default;
  virtual int rows() const = 0;
  virtual bool first_order() const = 0;       ///< velocity-level constraint
  /// 0 holonomic, 1 first order (velocity), 2 acceleration level (B q̈ + s = 0: the row's A is
  /// B, γ is s, and Φ, Φ̇ are written as 0). Kinds that are not acceleration-level keep the default.
  virtual int order() const { return first_order() ? 1 : 0; }
  virtual bool rheonomic() const = 0;         ///< depends explicitly on time
  virtual std::vector<int> points() const { return {}; }  ///< model points it reads
  /// phi: Φ or c; phid: Φ̇ (holonomic; equals phi for first-order rows); A; gamma.
  virtual void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi,
                        Eigen::Ref<Eigen::VectorXd> phid, Eigen::Ref<Eigen::MatrixXd> A,
                        Eigen::Ref<Eigen::VectorXd> gamma) const = 0;
  virtual std::string describe() const = 0;
  /// Doubles of scratch memory evaluate() needs (ConstraintInput::scratch).
  virtual int scratch_size() const { return 0; }
  /// evaluate() over dual numbers (for exact Jacobians): phi, phid, gamma (rows() each) and A
  /// (rows() × n, row-major) as functions of the dual t, q, q̇ of `in`; the value parts equal
  /// evaluate()'s results to rounding, the derivative parts are the exact directional
  /// derivatives along the seeds. The rows of A arrive zeroed (evaluate_constraints_dual).
  /// Kinds without it keep this default, which throws Error("constraint '<name>' (<describe()>)
  /// has no exact derivatives: ...").
  virtual void evaluate_dual(const ConstraintInputDual& in, JacobianScalar* phi, JacobianScalar* phid,
                             JacobianScalar* A, JacobianScalar* gamma) const;
  /// Dual numbers of scratch memory evaluate_dual() needs (ConstraintInputDual::scratch).
  virtual int scratch_size_dual() const { return 0; }
  /// Whether evaluate_dual() is provided: known when the constraint is built, so that
  /// build_problem refuses a kind without it under method: bdf or beside jerk rows (with the
  /// entry's location) instead of a throw in the middle of a run. Every kind written as a law
  /// (ConstraintLaw, law.hpp) has it; a hand-written kind that implements evaluate_dual
  /// overrides this to return true.
  virtual bool exact_derivatives() const { return false; }
  /// The function of time the constraint prescribes, if it has one (a point coordinate, joint
  /// trajectory or speed): recorded in trajectories under `record_as` when that is set.
  virtual const TimeFunction* target() const { return nullptr; }
  /// The rows as texts of the expression language (symbolic_form.hpp) over the model's joint
  /// and point names: Φ(q, t) for holonomic rows, c(q, q̇, t) for first-order ones; none for a
  /// kind without a closed form. A kind written as a law derives it from law<Formula>
  /// (ConstraintLaw, law.hpp); an expression constraint gives its own text.
  virtual std::optional<SymbolicForm> symbolic(const Model& /*model*/) const { return std::nullopt; }
  /// The geometry of the task, for kinds that hold a point on a known curve or surface.
  virtual std::optional<TaskGeometry> geometry() const { return std::nullopt; }

  std::string name;
  ConstraintOrigin origin = ConstraintOrigin::Programmed;
  std::string record_as;  ///< column name for target() in recorded trajectories; empty: none
};
using ConstraintPtr = std::shared_ptr<const Constraint>;
/// A constraint while it is being built: the factories return it so that the caller may still
/// name it (name, record_as) before publishing it as a ConstraintPtr (ConstraintSet::add).
using NewConstraint = std::shared_ptr<Constraint>;

/// Implicit surface f(r, t) = 0 in the world frame, with exact derivatives.
class ImplicitSurface {
 public:
  virtual ~ImplicitSurface() = default;
  struct Value {
    double f = 0;
    Vec3 grad = Vec3::Zero();     ///< ∂f/∂r
    Mat3 hess = Mat3::Zero();     ///< ∂²f/∂r²
    double ft = 0, ftt = 0;       ///< ∂f/∂t, ∂²f/∂t²
    Vec3 grad_t = Vec3::Zero();   ///< ∂²f/∂r∂t
  };
  virtual Value eval(const Vec3& r, double t) const = 0;
  /// Value over dual numbers: every entry as a function of the dual position r and time t.
  struct ValueDual {
    JacobianScalar f, ft, ftt;
    multibody::Vec3T<JacobianScalar> grad, grad_t;
    multibody::Mat3T<JacobianScalar> hess;
  };
  /// eval() over dual numbers (exact derivatives w.r.t. r and t through the dual parts; a
  /// rheonomic surface's ft, ftt need f''' of its functions of time). Surfaces without it keep
  /// this default, which throws Error naming the surface.
  virtual ValueDual eval_dual(const multibody::Vec3T<JacobianScalar>& r, const JacobianScalar& t) const;
  virtual bool rheonomic() const { return false; }
  /// Whether eval_dual() is provided (SurfaceLaw's surfaces; see Constraint::exact_derivatives).
  virtual bool exact_derivatives() const { return false; }
  virtual std::string describe() const = 0;
  /// f over Formulas (formula.hpp) at r = (x(P), y(P), z(P)) and t: the text of its symbolic
  /// form. SurfaceLaw's surfaces derive it from law<Formula>; others have none (nullopt).
  struct ValueFormula {
    Formula f, ft, ftt;
    multibody::Vec3T<Formula> grad, grad_t;
    multibody::Mat3T<Formula> hess;
  };
  virtual std::optional<ValueFormula> eval_formula(const multibody::Vec3T<Formula>& /*r*/, const Formula& /*t*/) const {
    return std::nullopt;
  }
  /// Its kind and numbers (TaskGeometry, without the point), where the kind is a known shape.
  virtual std::optional<TaskGeometry> geometry() const { return std::nullopt; }
};
using SurfacePtr = std::shared_ptr<const ImplicitSurface>;

/// ((x − cx)/a)² + ((y − cy)/b)² − 1: the elliptic cylinder about the z axis (a curve in x–y).
SurfacePtr elliptic_cylinder(Number a, Number b, Number cx = 0.0, Number cy = 0.0);
/// |r − c|² − R²
SurfacePtr sphere(const Number3& center, Number radius);
SurfacePtr sphere(const Vec3& center, double radius);
/// n·r − h(t): a (moving) plane, n normalised.
SurfacePtr plane(const Vec3& normal, TimeFunctionPtr offset);

// ---- ready-made kinds (each binds names to indices now and throws on unknown names) ----

/// A point on an implicit curve or surface: f(r_P, t) = 0.
NewConstraint point_on_surface(const Model& model, const std::string& point, SurfacePtr surface,
                               ConstraintOrigin origin = ConstraintOrigin::Programmed);
/// A point coordinate (axis 0: x, 1: y, 2: z) following a function of time: r_P,k − f(t) = 0.
NewConstraint point_coordinate(const Model& model, const std::string& point, int axis, TimeFunctionPtr f,
                               ConstraintOrigin origin = ConstraintOrigin::Programmed);
/// Prescribed joint motion: q_j − f(t) = 0.
NewConstraint joint_trajectory(const Model& model, const std::string& joint, TimeFunctionPtr f,
                               ConstraintOrigin origin = ConstraintOrigin::Programmed);
/// Two joints coupled linearly (a gear pair, a URDF <mimic>): q_joint − ratio·q_leader − offset = 0.
NewConstraint joint_coupling(const Model& model, const std::string& joint, const std::string& leader, Number ratio,
                             Number offset = 0.0, ConstraintOrigin origin = ConstraintOrigin::Material);
/// Two points coinciding (loop closure): r_P1 − r_P2 = 0 on the selected world axes
/// (default all three; a planar loop uses {0, 1}).
NewConstraint points_coincide(const Model& model, const std::string& p1, const std::string& p2,
                              std::vector<int> axes = {0, 1, 2},
                              ConstraintOrigin origin = ConstraintOrigin::Material);
/// No lateral slip of a wheel or knife edge at point P: (R_b a)·v_P = 0, a fixed in the body
/// carrying P (nonholonomic, first order).
NewConstraint knife_edge(const Model& model, const std::string& point, const Vec3& lateral_axis_in_body,
                         ConstraintOrigin origin = ConstraintOrigin::Material);
/// Prescribed speed of a point along a fixed world direction u: u·v_P − s(t) = 0 (first order).
NewConstraint point_speed(const Model& model, const std::string& point, const Vec3& direction,
                          TimeFunctionPtr speed, ConstraintOrigin origin = ConstraintOrigin::Programmed);

/// A constraint written as an expression over task quantities, differentiated exactly
/// (GiNaC, compiled to a tape; see expression.hpp) and chained through the point kinematics:
///   holonomic (first_order = false):  x(P), y(P), z(P)  world coordinates of point P,
///                                      q(j)  joint coordinate, t, and named parameters;
///   first order (first_order = true):  additionally vx(P), vy(P), vz(P) and qd(j).
/// E.g. "(x(E)/a)^2 + (y(E)/b)^2 - 1" with parameters {a, b}, or
/// "-(y(E))*vx(E) + x(E)*vy(E) - R*v0" for a prescribed speed along a circle.
/// For a holonomic Φ = f(w): A = Σ f_w ∂w/∂q, Φ̇ = f_w ẇ, γ = f_w ẅ|_{q̈=0} + ẇᵀ f_ww ẇ.
/// For a first-order c = f(w): A = Σ f_w ∂w/∂q̇, γ = Σ f_w ẇ|_{q̈=0}. Throws Error naming the
/// constraint for an expression that does not parse or uses unknown names.
NewConstraint expression_constraint(const Model& model, const std::string& name, const std::string& text,
                                    bool first_order = false,
                                    const std::map<std::string, double>& parameters = {},
                                    ConstraintOrigin origin = ConstraintOrigin::Programmed);
/// The same with the order given explicitly. ConstraintOrder::Acceleration (p = 2) adds
/// ax(P), ay(P), az(P) (point accelerations) and qdd(j) to the variables; the expression
/// must involve at least one of them and be linear in them (the form B(t, q, q̇) q̈ + s = 0
/// of the paper's eq. 2.1; checked symbolically). Then B = Σ f_w ∂w/∂q̈ over the acceleration
/// variables w and s = f evaluated with q̈ = 0 (point accelerations = their drifts d).
NewConstraint expression_constraint(const Model& model, const std::string& name, const std::string& text,
                                    ConstraintOrder order, const std::map<std::string, double>& parameters = {},
                                    ConstraintOrigin origin = ConstraintOrigin::Programmed);

/// The total time derivative of an expression along the motion, as a text of the same
/// language: d/dt f = ∂f/∂t + Σ ∂f/∂w ẇ with x(P) → vx(P) → ax(P) → jx(P) (likewise y, z) and
/// q(j) → qd(j) → qdd(j) → qddd(j); the partial derivatives exact (GiNaC), the parameters
/// substituted. A position expression gives its velocity-level row, an acceleration expression
/// its jerk-level row (`differentiate: true` in a scenario). Throws Error (naming `name`) for a
/// text that does not parse or that involves jerks (their derivative is of order 4).
std::string differentiate_expression_text(const Model& model, const std::string& name, const std::string& text,
                                          const std::map<std::string, double>& parameters = {});

/// Stacked constraints; row k of the stack belongs to constraint row_owner(k).
class ConstraintSet {
 public:
  void add(ConstraintPtr c);
  int rows() const { return rows_; }
  int size() const { return static_cast<int>(constraints_.size()); }
  const std::vector<ConstraintPtr>& constraints() const { return constraints_; }
  int row_offset(int k) const { return offsets_[k]; }
  int row_owner(int row) const;
  bool row_first_order(int row) const { return constraints_[row_owner(row)]->first_order(); }
  int row_order(int row) const { return constraints_[row_owner(row)]->order(); }  ///< see Constraint::order
  const std::vector<int>& points() const { return points_; }  ///< union of points read
  std::string row_name(int row) const;                         ///< "name[i]" or "name"
 private:
  std::vector<ConstraintPtr> constraints_;
  std::vector<int> offsets_;
  std::vector<int> points_;
  int rows_ = 0;
};

/// Workspace + result of evaluate_constraints, sized once for (model, set).
struct ConstraintEval {
  ConstraintEval(const Model& model, const ConstraintSet& set);
  Eigen::VectorXd phi, phid, gamma;  ///< size m
  Eigen::MatrixXd A;                 ///< m×n
  std::vector<PointState> points;    ///< indexed by model point index
  std::vector<double> scratch;       ///< for the constraints' evaluate() (largest scratch_size)
};

/// Workspace + result of evaluate_constraints_dual, sized once for (model, set).
struct ConstraintEvalDual {
  ConstraintEvalDual(const Model& model, const ConstraintSet& set);
  std::uint64_t model_id;                        ///< the model it was sized for
  int m, n;                                      ///< rows of the set, model.nv
  std::vector<JacobianScalar> phi, phid, gamma;  ///< size m (same meaning as ConstraintEval)
  std::vector<JacobianScalar> A;                 ///< m×n, row-major: A[row*n + col]
  std::vector<PointStateT<JacobianScalar>> points;  ///< indexed by model point index
  std::vector<JacobianScalar> scratch;           ///< for evaluate_dual (largest scratch_size_dual)
  // forward kinematics over dual numbers (the generic core)
  multibody::Bodies<JacobianScalar> bodies;
  multibody::Poses<JacobianScalar> poses;
  multibody::Motions<JacobianScalar> motion;
  std::vector<JacobianScalar> q;                 ///< q as a vector (forward_poses reads one)
};

/// ConstraintEval's quantities at (t, q, q̇) with t, q, q̇ dual numbers (q, q̇ arrays of
/// n = model.nv). The value parts equal evaluate_constraints' results (to rounding); the
/// derivative parts are the exact directional derivatives along the seeds of t, q and q̇
/// (forward kinematics, point kinematics with q̈ = 0 for the drifts, every constraint's
/// evaluate_dual over dual numbers, functions of time through f', f'', f'''). A plain double t
/// converts to an unseeded time: then functions of time enter as the same constants as with the
/// earlier double-t signature (derivative parts +0), and the results are the same. Seeding t
/// with 1, q with q̇ and q̇ with q̈ in one direction gives the total time derivatives along the
/// motion of Φ, Φ̇, A, γ (∂/∂t of the rheonomic rows included), for rows of every order ≤ 2
/// (tests/constraint_time_test.cpp). No heap allocation after the first call with a given ev.
/// Checks that ev belongs to this model and set; throws the Error of a kind without evaluate_dual.
void evaluate_constraints_dual(const Model& model, const ConstraintSet& set, ConstraintEvalDual& ev,
                               const JacobianScalar& t, const JacobianScalar* q, const JacobianScalar* qd);

/// Fills ev with Φ (or c), Φ̇, A and γ for all rows at (t, q, q̇). Runs forward kinematics and
/// the point kinematics of every point the set reads. No heap allocation. Checks that data and
/// ev belong to this model and set and the sizes of q, q̇ (finiteness is the caller's).
void evaluate_constraints(const Model& model, Data& data, const ConstraintSet& set, ConstraintEval& ev,
                          double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd);
/// The same right after unchecked::crba + unchecked::rnea_reusing_placements(q, q̇, q̈ = none,
/// gravity on) at this (q, q̇): reuses the joint placements data.liMi (only composes data.oMi)
/// and the body velocities data.v and accelerations data.a that RNEA left (its accelerations
/// are the drift accelerations plus the base acceleration −g, which is taken off). This skips a
/// second velocity recursion; tests/constraints_test checks it against evaluate_constraints.
void evaluate_constraints_after_bias_forces(const Model& model, Data& data, const ConstraintSet& set,
                                            ConstraintEval& ev, double t, const Eigen::VectorXd& q,
                                            const Eigen::VectorXd& qd);

/// Point kinematics of every listed point into `out` (FK must be done; uses data.v, data.a).
void compute_point_states(const Model& model, Data& data, const std::vector<int>& points,
                          const Eigen::VectorXd& qd, std::vector<PointState>& out);

}  // namespace refdyn
