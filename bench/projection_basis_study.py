#!/usr/bin/env python3
"""Accuracy of the two null-space bases of the projection route (issue 36, item 1).

The projection route solves  Nᵀ(M q̈ − F) = 0,  A q̈ = rhs  with a basis N of the null space of
A (m × n). Two bases are compared here on random problems, each against a 40-digit solution of
the KKT system [[M, Aᵀ], [A, 0]] [q̈; λ] = [F; rhs] (mpmath):

  partitioned  N = [I; −K_dc⁻¹ K_ic] (the paper's; 14a8d28's route at every size, and today's
               fixed-size kernels at n ≤ 4): q̈_p,dc = K_dc⁻¹ rhs, (NᵀMN) u = Nᵀ(F − M q̈_p);
  orthonormal  Z from a Householder QR of Aᵀ (today's route at other sizes,
               ReferenceDynamics::solve_projection_orthonormal).

Both are written here as refdyn computes them. The error is reported as
‖q̈ − q̈_ref‖∞ / (‖q̈_ref‖∞ · cond(M) · ε), binned by the partition's condition number
κ = ‖A‖₁ ‖K_dc⁻¹‖₁ (ReferenceDynamics::partition_condition). M: random SPD, cond(M) log-uniform
in [1e1, 1e6]; A: Gaussian with the chosen K_dc of condition log-uniform in [1, 10^3.5];
n = 5..15, m = 1..6.

Run: /usr/bin/python3 bench/projection_basis_study.py [cases]   (python3-numpy, python3-mpmath)
"""
import sys

import mpmath as mp
import numpy as np

mp.mp.dps = 40
EPS = np.finfo(float).eps
rng = np.random.default_rng(1)


def orthogonal(n):
    q, r = np.linalg.qr(rng.standard_normal((n, n)))
    return q * np.sign(np.diag(r))


def problem(n, m, cond_m, cond_k):
    lam = np.exp(rng.uniform(0, np.log(cond_m), n))
    lam[0], lam[-1] = 1.0, cond_m
    U = orthogonal(n)
    M = (U * lam) @ U.T
    M = (M + M.T) / 2
    A = rng.standard_normal((m, n))
    s = np.exp(np.linspace(0, -np.log(cond_k), m))
    A[:, :m] = (orthogonal(m) * s) @ orthogonal(m).T  # K_dc: the first m columns
    return M, A, rng.standard_normal(n), rng.standard_normal(m)


def kkt_reference(M, A, F, rhs):
    n, m = len(F), len(rhs)
    K = mp.zeros(n + m, n + m)
    b = mp.zeros(n + m, 1)
    for i in range(n):
        b[i] = mp.mpf(F[i])
        for j in range(n):
            K[i, j] = mp.mpf(M[i, j])
        for r in range(m):
            K[i, n + r] = K[n + r, i] = mp.mpf(A[r, i])
    for r in range(m):
        b[n + r] = mp.mpf(rhs[r])
    x = mp.lu_solve(K, b)
    return np.array([float(x[i]) for i in range(n)])


def partitioned(M, A, F, rhs):
    n, m = M.shape[0], A.shape[0]
    Ki = np.linalg.inv(A[:, :m])
    G = -Ki @ A[:, m:]
    qp = np.zeros(n)
    qp[:m] = Ki @ rhs
    N = np.vstack([G, np.eye(n - m)])
    L = np.linalg.cholesky(N.T @ M @ N)
    u = np.linalg.solve(L.T, np.linalg.solve(L, N.T @ (F - M @ qp)))
    kappa = np.abs(A).sum(0).max() * np.abs(Ki).sum(0).max()
    return qp + N @ u, kappa


def orthonormal(M, A, F, rhs):
    m = A.shape[0]
    Q, R = np.linalg.qr(A.T, mode="complete")
    y1 = np.linalg.solve(R[:m].T, rhs)
    W = Q.T @ M @ Q
    y2 = np.linalg.solve(W[m:, m:], (Q.T @ F)[m:] - W[m:, :m] @ y1)
    return Q @ np.concatenate([y1, y2])


def main():
    cases = int(sys.argv[1]) if len(sys.argv) > 1 else 1500
    bins = {}
    for _ in range(cases):
        n = int(rng.integers(5, 16))
        m = int(rng.integers(1, min(7, n)))
        cond_m = 10 ** rng.uniform(1, 6)
        M, A, F, rhs = problem(n, m, cond_m, 10 ** rng.uniform(0, 3.5))
        ref = kkt_reference(M, A, F, rhs)
        scale = np.abs(ref).max() * cond_m * EPS
        xp, kappa = partitioned(M, A, F, rhs)
        xo = orthonormal(M, A, F, rhs)
        b = min(int(np.floor(np.log10(kappa) * 2)), 7)
        bins.setdefault(b, []).append((np.abs(xp - ref).max() / scale, np.abs(xo - ref).max() / scale))
    print("| κ | cases | partitioned: median / max | orthonormal: median / max |")
    print("|---|---:|---:|---:|")
    for b in sorted(bins):
        e = np.array(bins[b])
        lo, hi = 10 ** (b / 2), 10 ** ((b + 1) / 2)
        label = f"{lo:.3g}–{hi:.3g}" if b < 7 else f"≥ {lo:.3g}"
        print(f"| {label} | {len(e)} | {np.median(e[:, 0]):.2g} / {e[:, 0].max():.2g} | "
              f"{np.median(e[:, 1]):.2g} / {e[:, 1].max():.2g} |")


if __name__ == "__main__":
    main()
