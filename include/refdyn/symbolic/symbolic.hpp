#pragma once
/// Generated reference dynamics: the equations of a Problem as formulas and as code.
///
/// generate_symbolic(problem) builds, with GiNaC, exact symbolic expressions of
///   M(q)                   mass matrix (Newton–Euler with unit accelerations)
///   c(q, q̇), g(q)          velocity-product and gravity terms (Newton–Euler)
///   Q(t, q, q̇, z), ż        generalized forces of the force elements and their states' rates
///   Φ (or c), Φ̇, A, γ       every constraint row: Φ̈ = A q̈ + γ (holonomic), ċ = A q̈ + γ (first
///                          order), A = ∂Φ/∂q or ∂c/∂q̇, γ = d/dt(A) q̇ + … by differentiation
///   K_ic, K_dc             the columns of A of the independent / dependent coordinates
/// in the symbols t, q_i, q̇_i, z_k and the scenario parameters the constraints and forces
/// name (kept symbolic; their values are the defaults of the generated code). Each constraint,
/// force element and function of time supplies its formula as a SymbolicForm
/// (symbolic_form.hpp; a constraint kind's or force element's is its law over Formula,
/// formula.hpp); kinds without one are reported by name.
///
/// Writers:
///   c_header(), c_source()  C99, only <math.h>: the blocks above with common-subexpression
///                           elimination, and PREFIX_rhs(t, x, p, xdot): ẋ = f(t, x) of the
///                           reference dynamics with x = [q, q̇, z], q̈ from the projected
///                           equations Nᵀ(M q̈ − F) = 0, A q̈ = −γ − 2αΦ̇ − β²Φ (holonomic rows),
///                           −γ − β₁c (first-order rows) by the null-space method (as
///                           ReferenceDynamics); returns 1 if K_dc is singular or NᵀMN not
///                           positive definite. M by the composite-rigid-body algorithm and
///                           c, g by Newton–Euler traced with the numbers folded, the solve
///                           written out for the sizes (docs/generate.md, "The C code").
///                           Jerk problems (a row of order 3): x = [q, q̇, q̈, z], PREFIX_jerk
///                           and the KKT system of JerkDynamics (docs/generate.md).
///   latex()                 a standalone LaTeX document (article class, amsmath only).
///   json()                  the expressions as texts of the expression language (^ for
///                           powers; abs, min, max, step, clamp, if for the piecewise functions).
/// Every writer's text is the same in every run (numbers exact in GiNaC, a canonical order of
/// operands: docs/generate.md, "The same text in every run").
/// The paper-literal force option (ReferenceDynamicsOptions::paper_literal_forces) is not
/// supported (Error).
#include "refdyn/scenario/problem.hpp"

#include <memory>
#include <string>

namespace refdyn {

struct SymbolicOptions {
  /// Prefix of the C identifiers (functions, types, macros); empty: "rd_" + the problem's name
  /// made an identifier. Must be a C identifier.
  std::string prefix;
  /// Common-subexpression elimination in the C code (off: every expression printed whole; for
  /// measuring the gain).
  bool cse = true;
};

struct SymbolicSummary {
  int nq = 0, nz = 0, constraints = 0, parameters = 0;
  double seconds = 0;            ///< generation time (symbolic work, not writing)
  long c_temporaries = 0;        ///< CSE temporaries in the C source (set by c_source())
  long c_operations = 0;         ///< arithmetic operations and calls in the C source (set by c_source())
};

class SymbolicReferenceDynamics {
 public:
  std::string c_header() const;
  std::string c_source() const;
  std::string latex() const;
  std::string json() const;
  /// The C identifier prefix.
  const std::string& prefix() const;
  const SymbolicSummary& summary() const;

  struct Impl;
  explicit SymbolicReferenceDynamics(std::shared_ptr<Impl> impl) : impl_(std::move(impl)) {}
  /// The expressions themselves (src/symbolic/internal.hpp; for the sensitivities).
  const Impl& impl() const { return *impl_; }

 private:
  std::shared_ptr<Impl> impl_;
};

/// Throws Error naming the constraint, force element or option that has no symbolic form.
SymbolicReferenceDynamics generate_symbolic(const Problem& problem, const SymbolicOptions& options = {});

}  // namespace refdyn
