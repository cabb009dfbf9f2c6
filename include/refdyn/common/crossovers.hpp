#pragma once
/// The size crossovers of refdyn's algorithms, in one place: from how many coordinates one
/// algorithm takes over from another, each with the measurement that set it (bench/README.md has
/// the tables; re-measure with the command named and change the number here only).
namespace refdyn {

/// Models with at least this many coordinates take the articulated-body algorithm in
/// forward_dynamics; smaller ones CRBA + Cholesky. Measured with
/// `dynamics_bench --benchmark_filter=FD` (bench/README.md, "Forward dynamics"; CPU-time medians
/// of CRBA + RNEA + Cholesky over ABA, 2026-11-25): 1.11 at 2, 1.19 at 3, 1.32 at 4, 1.67 at 7,
/// 1.88 at 15, 2.45 at 30, 4.35 at 60 DOF (the fused small-model sweep + Cholesky over ABA:
/// 1.01 at 2, 1.13 at 3). ABA is faster from 2 coordinates on; at 2 the two are within noise,
/// so one coordinate and two keep CRBA + Cholesky.
inline constexpr int kAbaFrom = 3;

/// From this many bodies the mass matrix is formed by the world-frame CRBA (composite inertias
/// in world axes, each M_ij a 6-term dot product) instead of the body-frame CRBA (crba.cpp). Set
/// when the world-frame sweep was written, from the mass-matrix rows of `dynamics_bench`: the
/// two tied at 6–7 bodies and the body-frame sweep was faster below (only the crossover was
/// recorded, not the table).
inline constexpr int kWorldCrbaFrom = 7;

/// Models with at least this many coordinates take the Lagrange (KKT) solver under
/// ReferenceSolver::Automatic (the default); smaller ones the projection. Measured with
/// `dynamics_bench --benchmark_filter=CFD` (bench/README.md, "Forward dynamics"; one evaluation
/// with 4 constraint rows (CFD) or 3 (CFDtip), CPU-time medians of projection over Lagrange with
/// its ABA factorization, two runs 2026-11-30, after the orthonormal solve took padded vector
/// kernels, reference/null_space_solve.hpp): 0.75/0.75 at 5, 0.76/0.76 at 6, 0.80/0.79 at 7
/// (CFDtip 0.84/0.83), 0.85/0.86 at 10, 0.96/0.97 at 15 (CFDtip 1.04/1.03), 1.23/1.22 at 20,
/// 1.22/1.22 at 24, 1.32/1.34 at 30, 2.10/2.12 at 60 DOF: they tie at 15, so Lagrange from 16
/// (it was 7 while the orthonormal solve ran plain loops, which tied at 6; 16 before that with
/// the partitioned basis).
inline constexpr int kLagrangeFrom = 16;

/// From this many coordinates the Lagrange (KKT) solver factors M by the articulated-body
/// algorithm instead of forming it: u = M⁻¹F by ABA, M⁻¹Aᵀ by its O(n) solves
/// (unchecked::aba_solve), Q_c = −Aᵀλ; mass() is then not filled. Measured with
/// `dynamics_bench --benchmark_filter=CFD` (4 rows, CPU-time medians, 2026-11-25; M + dense
/// Cholesky KKT in one run → ABA KKT in two later runs): 1349 → 1297/1296 ns at 7, 1868 →
/// 1757/1780 ns at 10, 2906 → 2604/2614 ns at 15, 3780 → 3462/3484 ns at 20, 6603 → 5220/5225 ns
/// at 30, 19.9 → 10.3/10.5 µs at 60 DOF: faster at every size measured (from 7; the CFD
/// benchmark has 4 rows), so from 7 on; below, the fixed-size dense kernels stay.
inline constexpr int kAbaLagrangeFrom = 7;

/// The orthonormal null-space solve (reference/null_space_solve.hpp) forms ZᵀMZ from an explicit
/// basis Z (2n²k + 4nmk flops, k = n − m) when that is fewer flops than the two-sided reflector
/// update of M (≈ 6n²m), i.e. when k (n + 2m) < 3 n m: few independent coordinates next to the
/// rows. Measured (a standalone loop over the two kernels, each built alone, random SPD M, median
/// of 31 runs, 2026-11-30; explicit / two-sided ns): 329/400 at (n, m) = (6, 4), 377/440 at
/// (7, 4), 362/381 at (7, 3), 573/605 at (10, 4), all on the explicit side of the rule;
/// 1275/1080 at (15, 4) and 1433/951 at (15, 3), on the two-sided side.
constexpr bool explicit_null_basis(int n, int m) { return (n - m) * (n + 2 * m) < 3 * n * m; }

}  // namespace refdyn
