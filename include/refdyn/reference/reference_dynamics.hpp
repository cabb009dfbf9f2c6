#pragma once
/// Reference dynamics (the generalized programmed motion equations, GPME, in the computational
/// form of Jarzębowska et al. 2024, eqs. (2.5)–(2.6), (4.9)): the model's unconstrained
/// dynamics M q̈ = F, F = Q − c − g, merged with all constraints (ConstraintSet) into one
/// system free of reaction forces.
///
/// Projection (the paper's method). The user partitions the velocities into
/// independent q̇_ic (the control inputs) and dependent q̇_dc. With A = [K_ic K_dc],
///     ∂q̇_dc/∂q̇_ic = −K_dc⁻¹ K_ic,   N = ∂q̇/∂q̇_ic  (n × (n−m)),
/// and the reduced equations are stacked with the stabilized constraints:
///     Nᵀ (M q̈ − F) = 0                             (n − m rows)
///     A q̈ = −γ − 2α Φ̇ − β² Φ      holonomic rows   (Baumgarte: Φ̈ + 2αΦ̇ + β²Φ = 0)
///     A q̈ = −γ − β₁ c              first-order rows (ċ + β₁ c = 0)
/// solved by the null-space method (q̈ = q̈_p + N u with A q̈_p = rhs, (NᵀMN) u = Nᵀ(F − M q̈_p)),
/// which is the same system with an (n−m)×(n−m) SPD solve.
///
/// Null-space basis. The equations only need *a* basis of the null space of A; N above is the
/// paper's partitioned one, and its rounding error grows with cond(K_dc)² · cond(M) (N carries
/// K_dc⁻¹; measured: 4.5e-6 in q̈ against 6.5e-9 for the KKT solve on the benchmark's 30-DOF chain
/// with κ = 639, 5e-9 relative with κ ≈ 1e4: tests/reference_dynamics_test.cpp,
/// ProjectionIsAsAccurateAsLagrangeOnLargeChains). So the solve uses:
///  - the partitioned N in the fixed-size kernels (n ≤ 4, 1 ≤ m < n: the paper's 3-DOF example
///    among them), where it is exact to rounding and the fastest; their outputs are unchanged;
///  - for every other size an orthonormal basis Z of the same space from a Householder QR
///    Aᵀ = Q [R; 0] (Z = the last n − m columns of Q): with y = Qᵀ q̈ = [y1; y2],
///    Rᵀ y1 = rhs and (ZᵀMZ) y2 = Zᵀ F − ZᵀMQ₁ y1, so no K_dc⁻¹ enters and the error is
///    cond(M)·ε like the KKT solve's, whatever the partition (equal to Lagrange to 1e-10 relative
///    to |q̈|∞ on random 30- and 60-DOF chains, also with partitions of κ ≈ 1e4). The kernel is
///    OrthonormalNullSpaceSolve (null_space_solve.hpp: vector operations over zero-padded
///    columns, ZᵀMZ from an explicit basis or a two-sided update of M, whichever has fewer
///    flops). With as many rows as coordinates there is no null space and no basis: q̈ = K_dc⁻¹
///    rhs with the partition's inverse (error cond(A)·ε, as any solve with A).
///    Chosen over one step of iterative refinement of the partitioned solve (measured too:
///    about as accurate for κ ≤ 1e4 and 15–20 % faster at 7–10 DOF, but 10 % slower at 60 DOF,
///    and its first solve, hence its convergence, still degrades with cond(K_dc)²).
/// The partition keeps its meaning on both routes: the independent coordinates q̇_ic (chosen or
/// given by `independent`), κ = partition_condition(), make_consistent, and the closed loop's
/// actuation (prepare_derivative factors it). Where it enters the solve (the partitioned basis,
/// and q̈ = K_dc⁻¹ rhs when m = n) λ comes from K_dcᵀλ = −Q_c,dc and a singular or
/// ill-conditioned K_dc (κ > max_condition) stops the run or, with automatic_partition, makes it
/// choose another partition. The orthonormal route does not use the partition at all: derivative()
/// does not factor it (κ is computed when asked for), λ comes from the same QR as q̈
/// (R λ = (Qᵀ(F − M q̈))₁: one factorization for q̈ and λ), and what is checked against max_condition
/// is the rows' own conditioning, max|R_jj| / min|R_jj| (dependent rows stop the run whatever
/// the partition; an ill-conditioned K_dc with well-conditioned rows does not).
/// Lagrange (KKT) form, the independent check: [[M, Aᵀ],[A, 0]] [q̈; λ] = [F; rhs], i.e.
///     M q̈ = F − Aᵀ λ,
/// and Q_c = −Aᵀλ = M q̈ − F is the generalized force the joints must add to realize the
/// programmed motion. Both give the same q̈ (to rounding) for any valid partition.
///
/// Acceleration-level rows (programmed constraints of order p = 2, B(t, q, q̇) q̈ + s = 0, see
/// docs/higher_order.md): the paper's GPME (2.4) for p = 2 reduce, by Tsenov's identity, to the
/// same projection Nᵀ(M q̈ − F) = 0 with N spanning the null space of the stacked rows, so such
/// a row enters the stack as it is: A = B, rhs = −s (no Baumgarte term: nothing to stabilize,
/// the row is satisfied algebraically at every evaluation). After each solve its Φ and Φ̇ in
/// constraints() hold the residual B q̈ + s.
///
/// Paper-literal forces (option): (2.5) adds Σ_k q̇_k ∂Q_k/∂q̇_i to the projected forces,
/// i.e. uses Nᵀ(Q + (∂Q/∂q̇)ᵀ q̇). That is not what Lagrange's equations give when Q depends
/// on q̇ (damping, friction, drives); it is available for comparison with the paper only.

#include "refdyn/common/crossovers.hpp"
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/common/error.hpp"
#include "refdyn/forces/force_elements.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/reference/null_space_solve.hpp"

#include <Eigen/LU>
#include <memory>
#include <string>
#include <vector>

namespace refdyn {

/// Projection (the paper's reduced form), Lagrange (KKT), or Automatic: resolved by the
/// ReferenceDynamics constructor to automatic_reference_solver(nq, rows) (options() then holds
/// the resolved solver).
enum class ReferenceSolver { Projection, Lagrange, Automatic };

/// (kLagrangeFrom and kAbaLagrangeFrom, the solver crossovers: refdyn/common/crossovers.hpp)

/// The solver ReferenceSolver::Automatic stands for with nq coordinates and `rows` constraint
/// rows: Lagrange from kLagrangeFrom coordinates on, else Projection (the paper's 3-DOF example
/// keeps the projection).
constexpr ReferenceSolver automatic_reference_solver(int nq, int /*rows*/) {
  return nq >= kLagrangeFrom ? ReferenceSolver::Lagrange : ReferenceSolver::Projection;
}

/// Whether the projection solver's solve uses the velocity partition with nq coordinates and
/// `rows` constraint rows: the partitioned basis of the fixed-size kernels (2 ≤ nq ≤ 4,
/// 1 ≤ rows < nq: the pairs REFDYN_FIXED_DISPATCH instantiates, src/reference/sized_dispatch.hpp)
/// and q̈ = K_dc⁻¹ rhs when rows = nq. Every other size solves with the orthonormal basis, which
/// uses none (see "Null-space basis" above).
constexpr bool projection_uses_partition(int nq, int rows) {
  return rows > 0 && (rows == nq || (nq >= 2 && nq <= 4 && rows < nq));
}

/// How the constraints are kept from drifting (docs/implicit.md, "Drift"):
///   Baumgarte  — the stabilized rows Φ̈ + 2αΦ̇ + β²Φ = 0, ċ + β₁c = 0 (the paper's method);
///   Projection — the plain rows Φ̈ = 0, ċ = 0 (α = β = β₁ = 0) and, after every accepted step,
///                (q, q̇) projected back onto Φ = 0, Φ̇ = 0, c = 0 (project_state);
///   Both       — Baumgarte's rows and the projection.
enum class Stabilization { Baumgarte, Projection, Both };
const char* to_string(Stabilization s);

struct ReferenceDynamicsOptions {
  double alpha = 100.0;              ///< Baumgarte α [1/s] (holonomic rows)
  double beta = 50.0;                ///< Baumgarte β [1/s] (holonomic rows)
  double beta_first_order = 50.0;    ///< β₁ [1/s] for first-order rows: ċ + β₁ c = 0
  /// Automatic (default): by size, automatic_reference_solver. The paper example and scenarios
  /// naming `solver: projection` set Projection explicitly.
  ReferenceSolver solver = ReferenceSolver::Automatic;
  /// Independent (control-input) coordinates by joint name; n − m of them. Empty: chosen
  /// automatically (best-conditioned K_dc) at the first evaluation.
  std::vector<std::string> independent;
  /// Re-choose the partition automatically when K_dc becomes ill-conditioned instead of
  /// stopping with an error.
  bool automatic_partition = false;
  double max_condition = 1e8;        ///< largest accepted κ = ‖A‖₁‖K_dc⁻¹‖₁ (see partition_condition)
  bool paper_literal_forces = false; ///< see the header comment
  /// Drift control. With Projection, the constructor sets α = β = β₁ = 0.
  Stabilization stabilization = Stabilization::Baumgarte;
  double projection_tolerance = 1e-12;  ///< project_state: largest |Φ|, |Φ̇|, |c| accepted
  int projection_max_iterations = 20;   ///< project_state: Newton iterations per level
  /// Throws refdyn::Error naming the bad field.
  void validate() const;
};

class ReferenceDynamics {
 public:
  /// Keeps references to model, forces and constraints: they must outlive this object.
  ReferenceDynamics(const Model& model, const ForceSet& forces, const ConstraintSet& constraints,
                    ReferenceDynamicsOptions options = {});

  int nq() const { return n_; }
  int num_constraints() const { return m_; }
  int num_force_states() const { return forces_.num_states(); }
  int state_size() const { return 2 * n_ + forces_.num_states(); }
  const Model& model() const { return model_; }
  const ForceSet& forces() const { return forces_; }
  const ConstraintSet& constraint_set() const { return constraints_; }
  const ReferenceDynamicsOptions& options() const { return opt_; }

  /// State x = [q; q̇; z] from q, q̇ and zero force-element states.
  Eigen::VectorXd make_state(const Eigen::VectorXd& q, const Eigen::VectorXd& qd) const;

  /// ẋ = [q̇; q̈; ż] at (t, x). No heap allocation (after the first call with an automatic
  /// partition). Throws NumericalFailure on a singular partition, Error on bad sizes.
  /// Without constraint rows, from kAbaFrom coordinates on (recursive_dynamics.hpp), q̈ comes
  /// from the articulated-body algorithm: mass() and bias() are then not filled and Q_c = 0.
  /// With the Lagrange solver from kAbaLagrangeFrom coordinates on, mass() is not filled.
  void derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot);
  /// derivative() in two halves, for a caller that needs the dynamics at (q, q̇) before it knows
  /// the applied forces (a controller on a constrained plant, whose efforts a force element reads):
  /// prepare_derivative fills bias(), constraints() and, when mass_filled(), mass(); then
  /// complete_derivative(t, x, xdot) with the same arguments evaluates the force elements and
  /// finishes. The two together give what derivative(t, x, xdot) gives, bit for bit.
  void prepare_derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot);
  void complete_derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot);
  /// True when derivative() fills mass() (not on the ABA routes).
  bool mass_filled() const { return !aba_ && !aba_lagrange_; }
  /// After prepare_derivative with the projection solver and constraint rows: the partition
  /// (independent(), dependent()) is factored at this state, K_dc⁻¹ in partition_inverse() (m × m)
  /// and G = −K_dc⁻¹ K_ic in partition_g() (m × k); complete_derivative uses that factorization.
  bool partition_factored() const { return factored_; }
  const Eigen::MatrixXd& partition_inverse() const { return Kinv_; }
  const Eigen::MatrixXd& partition_g() const { return G_; }

  // ---- results of the last derivative() call ----
  const Eigen::VectorXd& qdd() const { return qdd_; }
  const Eigen::VectorXd& lambda() const { return lambda_; }
  /// Q_c = M q̈ − F = −Aᵀλ: what the joints must add to realize the constraints.
  const Eigen::VectorXd& constraint_force() const { return Qc_; }
  const Eigen::VectorXd& applied_force() const { return Q_; }      ///< Q of the force elements
  const Eigen::VectorXd& bias() const { return data_.nle; }        ///< c + g (see derivative())
  const Eigen::MatrixXd& mass() const { return data_.M; }          ///< M (see derivative())
  const ConstraintEval& constraints() const { return ev_; }
  /// κ = ‖A‖₁ ‖K_dc⁻¹‖₁ at the last evaluation: K_dc's conditioning measured against the whole
  /// constraint Jacobian (so a tiny K_dc next to a large K_ic counts as ill-conditioned). On the
  /// orthonormal route, which does not factor the partition, it is factored here, at the last
  /// evaluation's A (the same κ, bit for bit, as factoring it during the evaluation).
  double partition_condition();
  const std::vector<int>& independent() const { return ind_; }
  const std::vector<int>& dependent() const { return dep_; }
  Data& data() { return data_; }

  /// Sets the partition by coordinate indices (n − m independent ones). Throws on a bad set.
  void set_independent(const std::vector<int>& independent);
  /// Chooses the dependent set with the best-conditioned K_dc at (t, q) (exhaustive when
  /// there are at most 500 candidate sets, else by column-pivoted QR). Returns cond(K_dc).
  double choose_partition(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd);

  /// Makes (q, q̇) consistent with the constraints at time t by Newton projection on the
  /// dependent coordinates (position rows, then velocity rows). Reports the correction.
  struct Consistency {
    Eigen::VectorXd q, qd;               ///< corrected
    Eigen::VectorXd dq, dqd;             ///< corrections applied
    double residual_before = 0, residual_after = 0;  ///< max |Φ|, |Φ̇|, |c| before/after
    int iterations = 0;
    bool converged = false;
  };
  Consistency make_consistent(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, double tol = 1e-12,
                              int max_iterations = 50);

  /// ∂f/∂x at (t, x), exact: J (state_size() × state_size()) is resized and written. Forward-mode
  /// dual numbers (JacobianScalar, ⌈2n / kJacobianDirections⌉ full sweeps) through the generic
  /// multibody core, the force elements and the constraints give the derivatives of the KKT
  /// system's residuals at the solved (q̈, λ); one factorization of M and of A M⁻¹ Aᵀ turns them
  /// into ∂q̈/∂x (docs/implicit.md). Evaluates derivative(t, x, ·) first, so the last-call
  /// results hold (t, x) afterwards. Throws Error when a force element or constraint has no
  /// dual evaluation or with paper_literal_forces (whose forces depend on ∂Q/∂q̇ itself), and
  /// NumericalFailure as derivative() does.
  void jacobian(double t, const Eigen::VectorXd& x, Eigen::MatrixXd& J);

  /// The least change of (q, q̇) in the metric of M(q) that puts x back on the constraints:
  ///     min ½ δqᵀ M δq   s.t. Φ(q + δq, t) = 0          (holonomic rows; Newton iterations
  ///                                                      δq = −M⁻¹Aᵀ(A M⁻¹ Aᵀ)⁻¹ Φ)
  ///     min ½ δq̇ᵀ M δq̇   s.t. Φ̇ = 0, c(q, q̇ + δq̇, t) = 0  (holonomic and first-order rows)
  /// to projection_tolerance (acceleration rows hold no state). x is corrected in place; z is
  /// left alone. Throws NumericalFailure naming the rows, the time and the residual when the
  /// iterations do not converge or A M⁻¹ Aᵀ is singular.
  struct StateProjection {
    double dq = 0, dqd = 0;            ///< ‖δq‖∞, ‖δq̇‖∞ applied
    double residual_before = 0, residual_after = 0;  ///< max |Φ|, |Φ̇|, |c|
    int iterations = 0;                ///< Newton iterations, both levels
  };
  StateProjection project_state(double t, Eigen::VectorXd& x);

  /// Worst constraint residual at (t, x): max over rows of |Φ| (holonomic) and |c| (first order);
  /// with acceleration rows, also |B q̈ + s| (then it evaluates derivative() once).
  double residual(double t, const Eigen::VectorXd& x);

 private:
  // derivative()'s stages, in order (reference_dynamics.cpp)
  void read_state(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& xdot);  // q, q̇; checks
  void unconstrained_aba(double t, const double* z);  // no rows, large model: q̈ by ABA
  void bias_and_constraints(double t);  // M, c + g; Φ, Φ̇, A, γ
  void forces_and_solve(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot);  // the rest, after bias_and_constraints
  void stabilized_rhs();                // F = Q − c − g; rhs of A q̈ = rhs
  void constraint_forces();             // Q_c; λ of the projection route
  void write_derivative(Eigen::VectorXd& xdot) const;  // ẋ = [q̇; q̈; ż] from the workspaces
  void solve_projection(double t);
  void solve_reduced_mass(double t, int k);  // (Nᵀ M N) u = r in NMN_, rk_
  void solve_lagrange(double t);
  void solve_lagrange_aba(double t);  // the KKT solve with ABA's factorization (kAbaLagrangeFrom)
  bool factor_partition();  // fills K_dc⁻¹, G, cond_; returns false if ill-conditioned
  template <int N, int Mr>
  bool factor_partition_sized();  // N = 0: sizes at run time
  template <int N, int Mr>
  void solve_projection_sized(double t);  // the partitioned basis N, fixed small sizes only
  void solve_projection_orthonormal(double t);  // the orthonormal basis from a QR of Aᵀ (other sizes); m = n: K_dc⁻¹ rhs
  template <int N, int Mr>
  void solve_lagrange_sized(double t);
  std::string partition_message(double t) const;

  const Model& model_;
  const ForceSet& forces_;
  const ConstraintSet& constraints_;
  ReferenceDynamicsOptions opt_;
  int n_, m_;
  Data data_;
  ConstraintEval ev_;
  std::vector<int> ind_, dep_;
  std::vector<char> first_order_row_;  ///< per constraint row: velocity-level (ċ + β₁c) or not
  std::vector<char> acceleration_row_;  ///< per constraint row: acceleration level (B q̈ + s = 0)
  bool has_acceleration_rows_ = false;
  bool aba_ = false;  ///< no constraint rows and a large model: derivative() takes the ABA route
  bool aba_lagrange_ = false;  ///< Lagrange solver from kAbaLagrangeFrom coordinates: KKT by ABA
  void acceleration_residuals();  // Φ = Φ̇ = B q̈ + s on acceleration rows after a solve
  Eigen::VectorXd xdot_;          // residual(): derivative workspace when there are acceleration rows
  bool partition_set_ = false;
  bool factored_ = false;  ///< the partition is factored at the state of prepare_derivative
  bool cond_current_ = true;  ///< cond_ belongs to the last evaluation's A (or nothing was evaluated)
  bool orthonormal_ = false;   ///< the projection solves with the orthonormal basis (m < n, not a fixed size)
  std::string dependent_rows_message(double t) const;  // the orthonormal route's rank failure
  void factor_for_projection(double t);  // the partition's factorization (re-chosen when allowed)
  // workspaces
  Eigen::VectorXd q_, qd_, Q_, F_, rhs_, qdd_, lambda_, Qc_, zdot_, tmp_n_, tmp_m_;
  Eigen::MatrixXd dQ_, Kdc_, Kic_, Kinv_, G_, Y_, Smm_, MN_, NMN_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_m_;
  Eigen::LLT<Eigen::MatrixXd> llt_m_, llt_k_;
  Eigen::VectorXd rk_;
  OrthonormalNullSpaceSolve orth_;  // the orthonormal route's solve and its storage
  double cond_ = 1.0;
  struct JacobianWork;  // src/reference/reference_jacobian.cpp; made at the first jacobian() call
  std::shared_ptr<JacobianWork> jac_;
};

}  // namespace refdyn
