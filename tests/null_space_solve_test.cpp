// The orthonormal null-space solve (refdyn/reference/null_space_solve.hpp) against an independent
// route: the KKT system [[M, Aᵀ], [A, 0]] [q̈; λ] = [f; rhs] solved in long double by a fully
// pivoted LU (q̈, and λ for multipliers()). Every column length the kernel is compiled for (L = 8, 12, 16, and run-time sizes),
// both ways of forming ZᵀMZ (explicit basis and two-sided update), m = 0 and m = n.
#include <gtest/gtest.h>

#include "refdyn/common/crossovers.hpp"
#include "refdyn/common/error.hpp"
#include "refdyn/reference/null_space_solve.hpp"

#include <Eigen/Dense>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <cmath>
#include <iostream>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <utility>

namespace {

using refdyn::OrthonormalNullSpaceSolve;
using LD = long double;
using MatL = Eigen::Matrix<LD, Eigen::Dynamic, Eigen::Dynamic>;
using VecL = Eigen::Matrix<LD, Eigen::Dynamic, 1>;

// SPD M with the given condition number: Q diag(σ) Qᵀ, σ log-spaced from 1 to cond.
Eigen::MatrixXd spd(std::mt19937& rng, int n, double cond) {
  std::normal_distribution<double> nd;
  const Eigen::MatrixXd X = Eigen::MatrixXd::NullaryExpr(n, n, [&] { return nd(rng); });
  const Eigen::MatrixXd Q = Eigen::HouseholderQR<Eigen::MatrixXd>(X).householderQ();
  Eigen::VectorXd s(n);
  for (int i = 0; i < n; ++i) s[i] = n == 1 ? 1.0 : std::pow(cond, double(i) / (n - 1));
  Eigen::MatrixXd M = Q * s.asDiagonal() * Q.transpose();
  return 0.5 * (M + M.transpose());
}

VecL kkt_reference(const Eigen::MatrixXd& M, const Eigen::MatrixXd& A, const Eigen::VectorXd& f,
                   const Eigen::VectorXd& rhs) {
  const int n = M.rows(), m = A.rows();
  MatL K = MatL::Zero(n + m, n + m);
  K.topLeftCorner(n, n) = M.cast<LD>();
  K.topRightCorner(n, m) = A.transpose().cast<LD>();
  K.bottomLeftCorner(m, n) = A.cast<LD>();
  VecL b(n + m);
  b << f.cast<LD>(), rhs.cast<LD>();
  return K.fullPivLu().solve(b);  // [q̈; λ]
}

}  // namespace

// Error bound: both the kernel and the KKT solve are backward stable, so the forward error of q̈
// is a modest multiple of cond(M)·ε relative to |q̈|∞ (A is a random Gaussian matrix, cond(A) of a
// few units to a few hundred). Measured worst over this test: printed; bound 4·n·cond(M)·ε.
TEST(OrthonormalNullSpaceSolve, EqualsTheKktSolutionForEverySizeAndRoute) {
  std::mt19937 rng(3011);
  std::normal_distribution<double> nd;
  std::set<std::pair<int, bool>> seen;  // (L, explicit basis) pairs exercised
  double worst = 0;                     // worst error in units of cond(M)·ε·|q̈|∞
  double worst_of_bound = 0;            // worst error as a fraction of the bound 4·n·cond(M)·ε
  int cases = 0;
  for (int n : {1, 2, 3, 5, 6, 7, 8, 9, 11, 12, 13, 15, 16, 17, 23, 24, 25, 40}) {
    for (int m : {0, 1, 2, 3, 4, 6, n - 1, n}) {
      if (m < 0 || m > n) continue;
      for (double cond : {1e1, 1e4, 1e6}) {
        const Eigen::MatrixXd M = spd(rng, n, cond);
        Eigen::MatrixXd A = Eigen::MatrixXd::NullaryExpr(m, n, [&] { return nd(rng); });
        if (m > 1) A.row(0) *= 1e3;  // rows of very different scales
        const Eigen::VectorXd f = Eigen::VectorXd::NullaryExpr(n, [&] { return nd(rng); });
        const Eigen::VectorXd rhs = Eigen::VectorXd::NullaryExpr(m, [&] { return nd(rng); });
        OrthonormalNullSpaceSolve solve(n, m);
        EXPECT_EQ(solve.explicit_basis(), refdyn::explicit_null_basis(n, m));
        seen.insert({solve.padded_rows(), solve.explicit_basis()});
        Eigen::VectorXd qdd = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN());
        ASSERT_TRUE(solve.solve(A.data(), M.data(), f.data(), rhs.data(), qdd.data()));
        const VecL ref = kkt_reference(M, A, f, rhs).head(n);
        const double scale = std::max(1.0, double(ref.cwiseAbs().maxCoeff()));
        const double err = double((qdd.cast<LD>() - ref).cwiseAbs().maxCoeff()) / scale;
        const double units = err / (cond * std::numeric_limits<double>::epsilon());
        const std::string where = "n " + std::to_string(n) + " m " + std::to_string(m) + " cond " + std::to_string(cond);
        EXPECT_LE(units, 4.0 * n) << where;
        // The rows hold to rounding whatever cond(M): A q̈ = rhs relative to |A|·|q̈|.
        if (m > 0) {
          const double row_err = (A * qdd - rhs).cwiseAbs().maxCoeff();
          EXPECT_LE(row_err, 64 * n * std::numeric_limits<double>::epsilon() * A.cwiseAbs().maxCoeff() *
                                 std::max(1.0, qdd.cwiseAbs().maxCoeff()))
              << where;
        }
        // A second solve with the same storage gives the same bits (no state carried over).
        Eigen::VectorXd again(n);
        ASSERT_TRUE(solve.solve(A.data(), M.data(), f.data(), rhs.data(), again.data()));
        EXPECT_EQ(qdd, again) << where;
        worst = std::max(worst, units);
        worst_of_bound = std::max(worst_of_bound, units / (4.0 * n));
        ++cases;
      }
    }
  }
  std::cout << "[ orthonormal null-space solve ] " << cases << " systems; worst error " << worst
            << " cond(M)·eps relative to |qdd| (" << worst_of_bound << " of the bound 4·n·cond(M)·eps)\n";
  for (int L : {8, 12, 16})
    for (bool ex : {false, true}) EXPECT_TRUE(seen.count({L, ex})) << "L " << L << (ex ? " explicit" : " two-sided");
  EXPECT_TRUE(seen.count({24, false}) && seen.count({24, true}) && seen.count({40, false}));
}

// λ of solve(…, lambda) and multipliers(f − M q̈), both from the solve's own QR, against the KKT
// λ, on both routes. Measured in force space, |Aᵀ(λ − λ_KKT)|∞ relative to |f|∞ + |M|∞|q̈|∞,
// which does not depend on how the rows are scaled (row 0 is 1e3 times the others). Bound:
// 8·n·cond(M)·ε; worst printed. Asking for λ leaves q̈ unchanged, bit for bit.
TEST(OrthonormalNullSpaceSolve, MultipliersEqualTheKktMultipliers) {
  std::mt19937 rng(3013);
  std::normal_distribution<double> nd;
  double worst = 0;
  int cases = 0;
  std::set<bool> seen;  // routes exercised
  for (int n : {1, 2, 5, 7, 9, 13, 16, 17, 30}) {
    for (int m : {1, 2, 4, 6, n - 1, n}) {
      if (m < 1 || m > n) continue;
      for (double cond : {1e1, 1e5}) {
        const Eigen::MatrixXd M = spd(rng, n, cond);
        Eigen::MatrixXd A = Eigen::MatrixXd::NullaryExpr(m, n, [&] { return nd(rng); });
        if (m > 1) A.row(0) *= 1e3;
        const Eigen::VectorXd f = Eigen::VectorXd::NullaryExpr(n, [&] { return nd(rng); });
        const Eigen::VectorXd rhs = Eigen::VectorXd::NullaryExpr(m, [&] { return nd(rng); });
        OrthonormalNullSpaceSolve solve(n, m);
        const double nan = std::numeric_limits<double>::quiet_NaN();
        Eigen::VectorXd qdd(n), qdd_alone(n), lambda = Eigen::VectorXd::Constant(m, nan),
                        lambda_after = Eigen::VectorXd::Constant(m, nan);
        ASSERT_TRUE(solve.solve(A.data(), M.data(), f.data(), rhs.data(), qdd_alone.data()));
        ASSERT_TRUE(solve.solve(A.data(), M.data(), f.data(), rhs.data(), qdd.data(), lambda.data()));
        const std::string where = "n " + std::to_string(n) + " m " + std::to_string(m) + " cond " +
                                  std::to_string(cond) + (solve.explicit_basis() ? " explicit" : " two-sided");
        EXPECT_EQ(qdd, qdd_alone) << where;
        const Eigen::VectorXd g = f - M * qdd;
        solve.multipliers(g.data(), lambda_after.data());
        const VecL ref = kkt_reference(M, A, f, rhs).tail(m);
        const double scale = f.cwiseAbs().maxCoeff() + M.cwiseAbs().rowwise().sum().maxCoeff() * qdd.cwiseAbs().maxCoeff();
        for (const Eigen::VectorXd* l : {&lambda, &lambda_after}) {
          const double err = double((A.transpose().cast<LD>() * (l->cast<LD>() - ref)).cwiseAbs().maxCoeff()) / scale;
          const double units = err / (cond * std::numeric_limits<double>::epsilon());
          EXPECT_LE(units, 8.0 * n) << where << (l == &lambda ? " solve" : " multipliers");
          worst = std::max(worst, units);
        }
        seen.insert(solve.explicit_basis());
        ++cases;
      }
    }
  }
  std::cout << "[ orthonormal null-space solve ] multipliers of " << cases << " systems; worst force error " << worst
            << " cond(M)·eps\n";
  EXPECT_EQ(seen.size(), 2u) << "both routes";
}

// row_condition(): 1 without rows, finite for independent rows, infinite or huge for dependent
// ones (a row repeated, a zero row); q̈ of dependent rows is then not to be used.
TEST(OrthonormalNullSpaceSolve, RowConditionFlagsDependentRows) {
  std::mt19937 rng(3014);
  std::normal_distribution<double> nd;
  for (auto [n, m] : {std::pair{7, 3}, std::pair{7, 6}, std::pair{12, 4}, std::pair{30, 5}}) {
    const Eigen::MatrixXd M = spd(rng, n, 10.0);
    Eigen::MatrixXd A = Eigen::MatrixXd::NullaryExpr(m, n, [&] { return nd(rng); });
    const Eigen::VectorXd f = Eigen::VectorXd::Ones(n), rhs = Eigen::VectorXd::Ones(m);
    Eigen::VectorXd qdd(n);
    OrthonormalNullSpaceSolve solve(n, m);
    solve.solve(A.data(), M.data(), f.data(), rhs.data(), qdd.data());
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A);
    const double cond2 = svd.singularValues()(0) / svd.singularValues()(m - 1);
    EXPECT_GE(solve.row_condition(), 1.0);
    EXPECT_LE(solve.row_condition(), cond2 * (1 + 1e-12)) << "a lower bound of cond2(A)";
    A.row(m - 1) = 2.0 * A.row(0);  // dependent
    solve.solve(A.data(), M.data(), f.data(), rhs.data(), qdd.data());
    EXPECT_GT(solve.row_condition(), 1e12) << n << " " << m;
    A.row(m - 1).setZero();
    solve.solve(A.data(), M.data(), f.data(), rhs.data(), qdd.data());
    EXPECT_EQ(solve.row_condition(), std::numeric_limits<double>::infinity()) << n << " " << m;
  }
  OrthonormalNullSpaceSolve none(4, 0);
  const Eigen::MatrixXd M = Eigen::MatrixXd::Identity(4, 4);
  const Eigen::VectorXd f = Eigen::VectorXd::Ones(4);
  Eigen::VectorXd qdd(4);
  ASSERT_TRUE(none.solve(nullptr, M.data(), f.data(), nullptr, qdd.data()));
  EXPECT_EQ(none.row_condition(), 1.0);
}

// Sizes: m ≤ n, and the column length the kernels run over.
TEST(OrthonormalNullSpaceSolve, SizesAndPadding) {
  EXPECT_THROW(OrthonormalNullSpaceSolve(3, 4), refdyn::Error);
  EXPECT_THROW(OrthonormalNullSpaceSolve(-1, 0), refdyn::Error);
  EXPECT_EQ(OrthonormalNullSpaceSolve::padded_rows(1), 8);
  EXPECT_EQ(OrthonormalNullSpaceSolve::padded_rows(8), 8);
  EXPECT_EQ(OrthonormalNullSpaceSolve::padded_rows(9), 12);
  EXPECT_EQ(OrthonormalNullSpaceSolve::padded_rows(13), 16);
  EXPECT_EQ(OrthonormalNullSpaceSolve::padded_rows(17), 24);
  EXPECT_EQ(OrthonormalNullSpaceSolve::padded_rows(60), 64);
}

// ZᵀMZ not positive definite (M indefinite on the null space of A): false, for the written
// Cholesky (k ≤ 16) and Eigen's (k > 16), on both routes.
TEST(OrthonormalNullSpaceSolve, ReportsAReducedMassThatIsNotPositiveDefinite) {
  for (auto [n, m] : {std::pair{7, 4}, std::pair{7, 1}, std::pair{30, 2}, std::pair{24, 20}}) {
    Eigen::MatrixXd M = Eigen::MatrixXd::Identity(n, n);
    M(n - 1, n - 1) = -1;  // e_{n−1} lies in the null space of A below
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m, n);
    for (int r = 0; r < m; ++r) A(r, r) = 1 + r;
    const Eigen::VectorXd f = Eigen::VectorXd::Ones(n), rhs = Eigen::VectorXd::Ones(m);
    Eigen::VectorXd qdd(n);
    OrthonormalNullSpaceSolve solve(n, m);
    EXPECT_FALSE(solve.solve(A.data(), M.data(), f.data(), rhs.data(), qdd.data())) << n << " " << m;
  }
}

// A call with a NaN in its input leaves nothing behind: the next call with valid input gives the
// bits a fresh solver gives (the padding rows are rewritten by every call; NaN · 0 would otherwise
// keep a NaN there), on both routes and at every column length.
TEST(OrthonormalNullSpaceSolve, ANonFiniteInputDoesNotPoisonLaterSolves) {
  std::mt19937 rng(3012);
  std::normal_distribution<double> nd;
  for (auto [n, m] : {std::pair{7, 4}, std::pair{7, 1}, std::pair{11, 5}, std::pair{11, 1}, std::pair{15, 2},
                      std::pair{20, 3}, std::pair{20, 15}}) {
    const Eigen::MatrixXd M = spd(rng, n, 1e3);
    const Eigen::MatrixXd A = Eigen::MatrixXd::NullaryExpr(m, n, [&] { return nd(rng); });
    const Eigen::VectorXd f = Eigen::VectorXd::NullaryExpr(n, [&] { return nd(rng); });
    const Eigen::VectorXd rhs = Eigen::VectorXd::NullaryExpr(m, [&] { return nd(rng); });
    Eigen::VectorXd fresh(n), after(n), scratch(n);
    OrthonormalNullSpaceSolve clean(n, m), used(n, m);
    ASSERT_TRUE(clean.solve(A.data(), M.data(), f.data(), rhs.data(), fresh.data()));
    const double nan = std::numeric_limits<double>::quiet_NaN();
    Eigen::MatrixXd Mbad = M, Abad = A;
    Eigen::VectorXd fbad = f;
    Mbad(n - 1, n - 1) = nan;
    Abad(0, n - 1) = std::numeric_limits<double>::infinity();
    fbad[n - 1] = nan;
    used.solve(Abad.data(), M.data(), f.data(), rhs.data(), scratch.data());
    used.solve(A.data(), Mbad.data(), f.data(), rhs.data(), scratch.data());
    used.solve(A.data(), M.data(), fbad.data(), rhs.data(), scratch.data());
    ASSERT_TRUE(used.solve(A.data(), M.data(), f.data(), rhs.data(), after.data()));
    EXPECT_EQ(after, fresh) << "n " << n << " m " << m << (used.explicit_basis() ? " explicit" : " two-sided");
  }
}
