// integrate() with IntegratorMethod::BDF: CVODES (SUNDIALS 6) with variable-order BDF, Newton
// iterations and a dense direct solver on the caller's exact Jacobian.
//
// The C callbacks never let an exception cross SUNDIALS: a NumericalFailure (a singular
// partition) or any other exception is kept and the callback returns −1 (unrecoverable); after
// CVode returns, a NumericalFailure becomes the summary's status and anything else is rethrown.
// A non-finite derivative returns +1 (recoverable: CVODE retries with a smaller step).
#include "bdf.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/reference/reference_dynamics.hpp"

#include <cvodes/cvodes.h>
#include <cvodes/cvodes_proj.h>
#include <nvector/nvector_serial.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <limits>
#include <optional>

namespace refdyn::detail {

namespace {

struct Callbacks {
  const OdeStageRhs& f;
  const OdeJacobian& jac;
  const OdeProjection& projection;
  Eigen::VectorXd x, dx, xp;
  Eigen::MatrixXd J;
  std::optional<NumericalFailure> failure;  // the first NumericalFailure raised by f or the Jacobian
  std::exception_ptr other;                 // any other exception: rethrown after the run
  /// The breakpoint CVODE steps toward (IntegratorOptions::breakpoints; +inf: none): f and ∂f/∂x
  /// are evaluated there, and past it, at the double below it (the left limit).
  double stop = std::numeric_limits<double>::infinity();
  double at(double t) const { return t >= stop ? std::nextafter(stop, -std::numeric_limits<double>::infinity()) : t; }
};

Eigen::Map<Eigen::VectorXd> view(N_Vector v) { return {N_VGetArrayPointer(v), N_VGetLength(v)}; }

template <class Body>
int guarded(Callbacks& c, Body&& body) {
  try {
    return body();
  } catch (const NumericalFailure& e) {
    if (!c.failure) c.failure.emplace(e);
  } catch (...) {
    if (!c.other) c.other = std::current_exception();
  }
  return -1;
}

int rhs(sunrealtype t, N_Vector y, N_Vector ydot, void* user) {
  auto& c = *static_cast<Callbacks*>(user);
  return guarded(c, [&] {
    c.x = view(y);
    c.f(Stage{}, c.at(t), c.x, c.dx);
    if (!c.dx.allFinite()) return 1;
    view(ydot) = c.dx;
    return 0;
  });
}

int jacobian(sunrealtype t, N_Vector y, N_Vector, SUNMatrix J, void* user, N_Vector, N_Vector, N_Vector) {
  auto& c = *static_cast<Callbacks*>(user);
  return guarded(c, [&] {
    c.x = view(y);
    c.jac(c.at(t), c.x, c.J);
    const auto n = static_cast<Eigen::Index>(SUNDenseMatrix_Rows(J));
    if (c.J.rows() != n || c.J.cols() != n)
      throw Error("integrate (bdf): the Jacobian has size " + std::to_string(c.J.rows()) + "x" +
                  std::to_string(c.J.cols()) + ", expected " + std::to_string(n) + "x" + std::to_string(n));
    if (!c.J.allFinite()) return 1;
    Eigen::Map<Eigen::MatrixXd>(SUNDenseMatrix_Data(J), n, n) = c.J;  // column-major, like Eigen
    return 0;
  });
}

// CVODE's projection after each step: corr = P(y) − y (the error estimate is not projected).
int project(sunrealtype t, N_Vector y, N_Vector corr, sunrealtype, N_Vector, void* user) {
  auto& c = *static_cast<Callbacks*>(user);
  return guarded(c, [&] {
    c.x = view(y);
    c.xp = c.x;
    c.projection(t, c.xp);
    view(corr) = c.xp - c.x;
    return 0;
  });
}

void quiet(int, const char*, const char*, char*, void*) {}  // messages are made from the flags

/// Owns the SUNDIALS objects of one run.
struct Cvode {
  SUNContext ctx = nullptr;
  N_Vector y = nullptr;
  SUNMatrix A = nullptr;
  SUNLinearSolver LS = nullptr;
  void* mem = nullptr;
  Cvode() = default;
  Cvode(const Cvode&) = delete;
  Cvode& operator=(const Cvode&) = delete;
  ~Cvode() {
    if (mem) CVodeFree(&mem);
    if (LS) SUNLinSolFree(LS);
    if (A) SUNMatDestroy(A);
    if (y) N_VDestroy(y);
    if (ctx) SUNContext_Free(&ctx);
  }
};

void check(int flag, const char* what) {
  if (flag < 0) throw Error(std::string("integrate (bdf): SUNDIALS ") + what + " failed (flag " + std::to_string(flag) + ")");
}

/// CVODE's counters since its last (re)start, added to those of the runs before (`before`).
void collect(void* mem, IntegrationSummary& s, const IntegrationSummary& before = {}) {
  long v = 0;
  CVodeGetNumSteps(mem, &v), s.steps = before.steps + v;
  CVodeGetNumRhsEvals(mem, &v), s.rhs_evaluations = before.rhs_evaluations + v;
  CVodeGetNumJacEvals(mem, &v), s.jacobian_evaluations = before.jacobian_evaluations + v;
  CVodeGetNumNonlinSolvIters(mem, &v), s.newton_iterations = before.newton_iterations + v;
  CVodeGetNumNonlinSolvConvFails(mem, &v), s.newton_failures = before.newton_failures + v;
  CVodeGetNumErrTestFails(mem, &v), s.error_test_failures = before.error_test_failures + v;
  s.rejected_steps = s.newton_failures + s.error_test_failures;
}

/// The summary's status and message for a failed CVode call at time t (last step h).
void describe_failure(int flag, double t, double h, const IntegratorOptions& o, IntegrationSummary& s) {
  const std::string at = "at t = " + fmt(t) + " s";
  switch (flag) {
    case CV_TOO_MUCH_WORK:
      s.status = IntegrationStatus::MaxSteps;
      s.message = "stopped " + at + " after max_steps = " + std::to_string(o.max_steps) + " steps";
      return;
    case CV_TOO_MUCH_ACC:
      s.status = IntegrationStatus::StepSizeCollapse;
      s.message = at + " the tolerances rtol = " + fmt(o.rtol) + ", atol = " + fmt(o.atol) +
                  " cannot be met in floating point (hint: larger tolerances)";
      return;
    case CV_ERR_FAILURE:
    case CV_CONV_FAILURE:
      s.status = IntegrationStatus::StepSizeCollapse;
      s.message = at + " BDF could not take a step: " +
                  (flag == CV_ERR_FAILURE ? "the local error test failed" : "the Newton iteration did not converge") +
                  " repeatedly, down to the step h = " + fmt(h) + " s (min_step = " + fmt(o.min_step) +
                  " s): the solution is singular or discontinuous there";
      return;
    case CV_REPTD_RHSFUNC_ERR:
    case CV_UNREC_RHSFUNC_ERR:
    case CV_FIRST_RHSFUNC_ERR:
    case CV_LSETUP_FAIL:
      s.status = IntegrationStatus::NonFinite;
      s.message = at + " the right-hand side or its Jacobian became NaN or infinite and smaller steps did not help "
                  "(the run diverged)";
      return;
    default: {
      char* name = CVodeGetReturnFlagName(flag);
      s.status = IntegrationStatus::NumericalFailure;
      s.message = at + " CVODE stopped: " + (name ? name : "unknown flag " + std::to_string(flag));
      std::free(name);
    }
  }
}

}  // namespace

IntegrationSummary integrate_bdf(const OdeStageRhs& f, const OdeJacobian& jac, Eigen::VectorXd& x,
                                 const IntegratorOptions& o, const OdeObserver& obs, const OdeProjection& projection) {
  IntegrationSummary s;
  s.t_end = o.t0;
  if (obs && !obs(o.t0, x)) {
    s.status = IntegrationStatus::Stopped;
    s.message = "stopped by the observer at t = " + fmt(o.t0) + " s";
    return s;
  }
  const auto n = static_cast<sunindextype>(x.size());
  Callbacks cb{f, jac, projection, x, Eigen::VectorXd(x.size()), x, Eigen::MatrixXd(x.size(), x.size()), std::nullopt,
               nullptr};
  Cvode cv;
  check(SUNContext_Create(nullptr, &cv.ctx), "SUNContext_Create");
  cv.y = N_VNew_Serial(n, cv.ctx);
  if (!cv.y) throw std::bad_alloc();
  view(cv.y) = x;
  cv.mem = CVodeCreate(CV_BDF, cv.ctx);
  if (!cv.mem) throw std::bad_alloc();
  check(CVodeSetErrHandlerFn(cv.mem, quiet, nullptr), "CVodeSetErrHandlerFn");
  check(CVodeInit(cv.mem, rhs, o.t0, cv.y), "CVodeInit");
  check(CVodeSStolerances(cv.mem, o.rtol, o.atol), "CVodeSStolerances");
  check(CVodeSetUserData(cv.mem, &cb), "CVodeSetUserData");
  cv.A = SUNDenseMatrix(n, n, cv.ctx);
  cv.LS = SUNLinSol_Dense(cv.y, cv.A, cv.ctx);
  if (!cv.A || !cv.LS) throw std::bad_alloc();
  check(CVodeSetLinearSolver(cv.mem, cv.LS, cv.A), "CVodeSetLinearSolver");
  check(CVodeSetJacFn(cv.mem, jacobian), "CVodeSetJacFn");
  check(CVodeSetMaxOrd(cv.mem, o.max_order), "CVodeSetMaxOrd");
  check(CVodeSetMinStep(cv.mem, o.min_step), "CVodeSetMinStep");
  // The breakpoints inside (t0, t1): CVODE stops on each (tstop) and restarts there (CVodeReInit).
  std::vector<double> breaks;
  for (double b : o.breakpoints)
    if (b > o.t0 && b < o.t1 && (breaks.empty() || b > breaks.back())) breaks.push_back(b);
  size_t next_break = 0;
  if (!breaks.empty()) cb.stop = breaks[0];
  check(CVodeSetStopTime(cv.mem, breaks.empty() ? o.t1 : breaks[0]), "CVodeSetStopTime");  // f is not asked past it
  if (projection) {
    check(CVodeSetProjFn(cv.mem, project), "CVodeSetProjFn");
    check(CVodeSetProjErrEst(cv.mem, SUNFALSE), "CVodeSetProjErrEst");
  }

  const double dt_out = o.output_interval > 0 ? o.output_interval : o.step;
  IntegrationSummary restarted;  // CVODE's counters of the runs before the last restart
  for (long k = 1;; ++k) {
    const double tout = std::min(o.t0 + k * dt_out, o.t1);
    long taken = 0;
    int flag = 0;
    sunrealtype reached = o.t0;
    // Through the breakpoints up to tout: to each, then a restart there (on tout itself the state
    // is the one CVODE stopped with).
    bool on_break = false;
    while (next_break < breaks.size() && breaks[next_break] <= tout) {
      CVodeGetNumSteps(cv.mem, &taken);
      check(CVodeSetMaxNumSteps(cv.mem, std::max(1L, o.max_steps - restarted.steps - taken)), "CVodeSetMaxNumSteps");
      flag = CVode(cv.mem, breaks[next_break], cv.y, &reached, CV_NORMAL);
      if (flag < 0) break;
      collect(cv.mem, restarted, restarted);
      const double b = breaks[next_break++];
      check(CVodeReInit(cv.mem, b, cv.y), "CVodeReInit");
      cb.stop = next_break < breaks.size() ? breaks[next_break] : std::numeric_limits<double>::infinity();
      check(CVodeSetStopTime(cv.mem, next_break < breaks.size() ? breaks[next_break] : o.t1), "CVodeSetStopTime");
      on_break = b == tout;
    }
    CVodeGetNumSteps(cv.mem, &taken);
    check(CVodeSetMaxNumSteps(cv.mem, std::max(1L, o.max_steps - restarted.steps - taken)), "CVodeSetMaxNumSteps");
    if (flag >= 0 && !on_break) flag = CVode(cv.mem, tout, cv.y, &reached, CV_NORMAL);
    if (cb.other) std::rethrow_exception(cb.other);
    if (flag < 0) {
      collect(cv.mem, s, restarted);
      sunrealtype h = 0;
      CVodeGetCurrentStep(cv.mem, &h);
      if (cb.failure) {
        s.status = IntegrationStatus::NumericalFailure;
        s.message = cb.failure->what();
      } else {
        describe_failure(flag, reached, h, o, s);
      }
      return s;  // x holds the state of the last output
    }
    x = view(cv.y);
    // CVODE's output is interpolated between its (projected) steps: project the sample too, so
    // that every recorded state is on the constraints (CVODE's own state is left alone).
    if (projection) try {
        projection(tout, x);
      } catch (const NumericalFailure& e) {
        collect(cv.mem, s, restarted);
        s.status = IntegrationStatus::NumericalFailure;
        s.message = e.what();
        return s;
      }
    s.t_end = tout;
    if (obs && !obs(tout, x)) {
      collect(cv.mem, s, restarted);
      s.status = IntegrationStatus::Stopped;
      s.message = "stopped by the observer at t = " + fmt(tout) + " s";
      return s;
    }
    if (tout >= o.t1) break;
  }
  collect(cv.mem, s, restarted);
  s.t_end = o.t1;
  return s;
}

}  // namespace refdyn::detail
