#pragma once
// Private to src/reference/reference_dynamics.cpp: the size dispatch of ReferenceDynamics' small
// dense kernels (factor_partition, the projection and Lagrange solves). Used inside
// ReferenceDynamics members (n_, m_).
//
// The small dense glue of the projection route (factor_partition, solve_projection) is written
// as plain loops over column-major storage, with every size, index list and buffer in a local
// (restrict) pointer: for the sizes of interest (m, n of a few) Eigen's dynamic-size expression
// set-up costs more than the flops, and stores through double* would otherwise force the
// members to be reloaded in every iteration. The loops are templates on the sizes: N = 0 reads
// n, m at run time; the common small (n, m) pairs are instantiated with compile-time sizes,
// which the compiler unrolls completely (one source, no second copy of the algorithm). The
// partitioned solve (solve_projection_sized) exists only for those fixed pairs; every other size
// takes solve_projection_orthonormal (header comment: why). The KKT route (solve_lagrange) is
// dispatched the same way onto fixed- or dynamic-size Eigen objects.
// The (n, m) pairs below are those refdyn::projection_uses_partition names (reference_dynamics.hpp,
// with m = n): keep the two in step.
#define REFDYN_FIXED_DISPATCH(call, args)                     \
  if (n_ == 2 && m_ == 1) return call<2, 1> args;             \
  if (n_ == 3 && m_ == 1) return call<3, 1> args;             \
  if (n_ == 3 && m_ == 2) return call<3, 2> args;             \
  if (n_ == 4 && m_ == 1) return call<4, 1> args;             \
  if (n_ == 4 && m_ == 2) return call<4, 2> args;             \
  if (n_ == 4 && m_ == 3) return call<4, 3> args;
#define REFDYN_SIZED_DISPATCH(call, args) \
  REFDYN_FIXED_DISPATCH(call, args)       \
  return call<0, 0> args;
