#pragma once
// Private to the generator (src/symbolic/*.cpp).
//   model.cpp     the bodies of a Model as GiNaC expressions (the kinematics and Newton–Euler
//                 are the generic core's, refdyn/multibody/, instantiated for GiNaC::ex)
//   generate.cpp  the reference dynamics of a Problem: M, c, g, Q, ż, Φ, Φ̇, A, γ, partition
//   tape.cpp     the canonical graph of double operations the writers print from (tape.hpp)
//   emit_c.cpp    C99 writer (with common-subexpression elimination)
//   emit.cpp      LaTeX and JSON writers (printer.hpp: number formatting)
#include "refdyn/multibody/model.hpp"
#include "refdyn/scenario/spec.hpp"
#include "refdyn/symbolic/symbolic.hpp"
#include "refdyn/multibody/generic_dynamics.hpp"
#include "ginac_scalar.hpp"

#include <ginac/ginac.h>

#include <array>
#include <functional>
#include <string>
#include <vector>

namespace refdyn::symbolic_detail {

using GiNaC::ex;
using Vec3s = multibody::Vec3T<ex>;
using Mat3s = multibody::Mat3T<ex>;  // row-major

/// A vector of the model as numbers, entries within 4 ulp of its largest one written as 0.
Vec3s clean(const Vec3& v);
/// A rotation as numbers, entries within 4 ulp of 0 or ±1 written exactly.
Mat3s rotation(const Mat3& R);

/// The bodies of the compiled model with symbolic geometry and inertia (numbers, or expressions
/// of the scenario's parameters when the scenario wrote them so): the generic core's bodies
/// (refdyn/multibody/body.hpp) over GiNaC expressions.
using SymbolicBody = multibody::Body<ex>;
using SymbolicPoint = multibody::Point<ex>;
using SymbolicBodies = multibody::Bodies<ex>;

/// How the generator lifts the compiled model's numbers (multibody::bodies_from_model<ex>(model,
/// CleanLift{})): rotation entries within 4 ulp of 0 or ±1, and vector and inertia entries within
/// 4 ulp of their largest, are written exactly (a DH twist of 90° leaves 6e-17); the axis and the
/// scalars as they are.
struct CleanLift {
  ex scalar(double v) const;
  Vec3s axis(const Vec3& v) const;
  Vec3s vector(const Vec3& v) const;
  Mat3s rotation(const Mat3& R) const;
  Mat3s inertia(const Mat3& I) const;
};
/// The same bodies from the numbers of the scenario's `model:` section as the reader read them
/// (Problem::model_numbers): `value` turns a Quantity into an expression of the parameters (its
/// text). The fold (fixed joints, DH link offsets, the base, the points) is build_model's own,
/// multibody::fold_links over GiNaC::ex (refdyn/multibody/detail/fold.hpp).
using QuantityValue = std::function<ex(const Quantity&)>;
SymbolicBodies bodies_from_numbers(const Model& model, const ModelNumbers& numbers, const QuantityValue& value);

/// World kinematics and dynamics as GiNaC expressions of the coordinate symbols: the generic
/// core (refdyn/multibody/) instantiated for GiNaC::ex.
struct SymbolicModel {
  SymbolicBodies bodies;
  Vec3 gravity;
  std::vector<ex> q;               ///< coordinate symbols
  multibody::Poses<ex> poses;      ///< local and world poses of every body at q
  /// Joint-space inverse dynamics M q̈ + c + g at the given symbolic q̈ (empty: 0) and q̇ (empty:
  /// 0), with or without gravity (multibody::inverse_dynamics, Newton–Euler in body frames).
  std::vector<ex> inverse_dynamics(const std::vector<ex>& qd, const std::vector<ex>& qdd, bool gravity) const;
};

SymbolicModel symbolic_model(const SymbolicBodies& bodies, const Vec3& gravity, const std::vector<ex>& q);

}  // namespace refdyn::symbolic_detail

namespace refdyn {

struct SymbolicReferenceDynamics::Impl {
  std::string name;
  std::string prefix;
  int n = 0, nz = 0, m = 0;
  std::vector<std::string> joints, states;
  std::vector<std::string> row_names, row_origin;
  std::vector<char> row_order;  ///< per row its order: 0 position, 1 velocity, 2 acceleration, 3 jerk
  std::vector<int> independent, dependent;
  std::vector<std::string> param_names;
  std::vector<double> param_values;
  double alpha = 0, beta = 0, beta1 = 0, kappa = 50;
  bool cse = true;
  /// A jerk problem (a row of order 3): state x = [q, q̇, q̈, z], ẋ = [q̇, q̈, q⃛, ż].
  bool jerk = false;

  symbolic_detail::SymbolicModel model;  ///< bodies and poses (the C writer traces M, c, g from them)
  GiNaC::realsymbol t;
  std::vector<GiNaC::realsymbol> q, qd, qdd, z, params;  ///< qdd: state in jerk problems, else only inside acceleration rows
  std::vector<GiNaC::realsymbol> qddd;                  ///< only inside jerk rows
  /// The gains as symbols (fields rd_alpha, rd_beta, rd_beta1, rd_kappa of PREFIX_params) where
  /// they enter expressions: the stabilized rows ψ of a jerk problem.
  GiNaC::realsymbol alpha_s, beta_s, beta1_s, kappa_s;
  std::vector<GiNaC::ex> M;                 ///< n×n row-major
  std::vector<GiNaC::ex> c, g, Q, zdot;     ///< n, n, n, nz
  std::vector<GiNaC::ex> Qact;              ///< n: the part of Q from actuator elements (drives, efforts)
  std::vector<GiNaC::ex> phi, phid, A, gamma;  ///< m, m, m×n, m
  /// Jerk problems: R = M q̈ + c + g − Q and Ṙ at q⃛ = 0 (n); G (m×n, A of the rows of order ≤ 2,
  /// B of the jerk rows) and Ġ; per row ψ (stabilized acceleration-level row; 0 for jerk rows)
  /// and the jerk-level right-hand side b: G q⃛ = b, b = −ψ̇|q⃛=0 − κψ, or −s for a jerk row.
  std::vector<GiNaC::ex> R, Rdot, G, Gdot, psi, b;
  /// c + g in one Newton–Euler pass (n) and, per row, the stabilized right-hand side of the
  /// acceleration level, A q̈ = rhs (−γ − 2αΦ̇ − β²Φ, −γ − β₁c, −γ; gains as symbols): what
  /// PREFIX_rhs evaluates in one block with M, Q, ż and A (shared kinematics, one CSE).
  std::vector<GiNaC::ex> cg, rhs;
  SymbolicSummary summary;
};

}  // namespace refdyn
