#pragma once
/// Inverse dynamics of a Model over the Jacobian scalar (dual.hpp): the generic core's
/// Newton–Euler (generic_dynamics.hpp) with the model's bodies converted once per thread and model.
/// Used by the exact Jacobians of implicit integration (the reference dynamics, the plant, the
/// controllers that use the model).
#include "refdyn/multibody/dual.hpp"
#include "refdyn/multibody/model.hpp"

namespace refdyn {

/// τ = M(q) q̈ + c(q, q̇) (+ g(q) when with_gravity) → tau[0, nv). qd, qdd: nv values or nullptr
/// (zero). Not reentrant across models within one thread's call (the workspace is per thread).
void inverse_dynamics_dual(const Model& model, const JacobianScalar* q, const JacobianScalar* qd,
                           const JacobianScalar* qdd, bool with_gravity, JacobianScalar* tau);

}  // namespace refdyn
