#pragma once
/// Errors raised by refdyn for bad user input (sizes, non-finite numbers, unknown names,
/// invalid physical parameters). Numerical outcomes (a diverging simulation, a singular
/// partition met during integration) are reported in a Summary, not thrown.

#include <Eigen/Core>

#include <cmath>
#include <stdexcept>
#include <string>
#include <string_view>

namespace refdyn {

/// The one error type every refdyn library error derives from.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A numerical outcome at time t, not bad input: the equations cannot be formed there (a
/// singular partition or mass matrix, a state that is not finite). Thrown by the dynamics'
/// derivative(); integrators catch it and report it in their Summary, with the time.
class NumericalFailure : public Error {
 public:
  NumericalFailure(double t, const std::string& msg) : Error(msg), time(t) {}
  double time;
};

/// Builds "what: expected E, got G (hint: H)".
std::string expected_got(std::string_view what, std::string_view expected, std::string_view got,
                         std::string_view hint = {});

/// Throws Error unless `got == expected`; `what` names the argument, e.g. "q".
void check_size(std::string_view what, Eigen::Index expected, Eigen::Index got,
                std::string_view hint = {});

/// Throws Error naming the first non-finite entry of `x`.
template <typename Derived>
void check_finite(std::string_view what, const Eigen::MatrixBase<Derived>& x) {
  for (Eigen::Index j = 0; j < x.cols(); ++j)
    for (Eigen::Index i = 0; i < x.rows(); ++i)
      if (!std::isfinite(x(i, j))) {
        std::string where = x.cols() == 1 ? "[" + std::to_string(i) + "]"
                                          : "(" + std::to_string(i) + "," + std::to_string(j) + ")";
        throw Error(std::string(what) + where + ": expected a finite number, got " +
                    std::to_string(x(i, j)) + " (hint: check the inputs that produced it)");
      }
}

/// Size and finiteness of a state-like vector argument, in one call.
template <typename Derived>
void check_vector(std::string_view what, const Eigen::MatrixBase<Derived>& x, Eigen::Index expected,
                  std::string_view hint = {}) {
  check_size(what, expected, x.size(), hint);
  check_finite(what, x);
}

}  // namespace refdyn
