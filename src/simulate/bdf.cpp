// integrate_bdf: CVODES (SUNDIALS 6) with BDF, Newton iterations and a dense direct solver on the
// caller's exact Jacobian. The C callbacks never let an exception cross SUNDIALS: they record it
// and return −1 (unrecoverable); a non-finite derivative returns +1 (recoverable: CVODE retries
// with a smaller step).
#include "refdyn/simulate/bdf.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"

#include <cvodes/cvodes.h>
#include <nvector/nvector_serial.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <cmath>
#include <cstdlib>
#include <memory>

namespace refdyn {

namespace {

struct Callbacks {
  const BdfRhs& f;
  const BdfJacobian& jac;
  Eigen::VectorXd x, dx;
  Eigen::MatrixXd J;
  std::string error;  // an exception from the caller's functions
};

Eigen::Map<Eigen::VectorXd> view(N_Vector v) { return {N_VGetArrayPointer(v), N_VGetLength(v)}; }

int rhs(sunrealtype t, N_Vector y, N_Vector ydot, void* user) {
  auto& c = *static_cast<Callbacks*>(user);
  try {
    c.x = view(y);
    c.f(t, c.x, c.dx);
    if (!c.dx.allFinite()) return 1;
    view(ydot) = c.dx;
    return 0;
  } catch (const std::exception& e) {
    c.error = e.what();
    return -1;
  }
}

int jacobian(sunrealtype t, N_Vector y, N_Vector, SUNMatrix J, void* user, N_Vector, N_Vector, N_Vector) {
  auto& c = *static_cast<Callbacks*>(user);
  try {
    c.x = view(y);
    c.jac(t, c.x, c.J);
    if (!c.J.allFinite()) return 1;
    const auto n = static_cast<Eigen::Index>(SUNDenseMatrix_Rows(J));
    Eigen::Map<Eigen::MatrixXd>(SUNDenseMatrix_Data(J), n, n) = c.J;  // column-major, like Eigen
    return 0;
  } catch (const std::exception& e) {
    c.error = e.what();
    return -1;
  }
}

void quiet(int, const char*, const char*, char*, void*) {}  // messages are taken from the flags

/// Owns the SUNDIALS objects of one run.
struct Cvode {
  SUNContext ctx = nullptr;
  N_Vector y = nullptr;
  SUNMatrix A = nullptr;
  SUNLinearSolver LS = nullptr;
  void* mem = nullptr;
  ~Cvode() {
    if (mem) CVodeFree(&mem);
    if (LS) SUNLinSolFree(LS);
    if (A) SUNMatDestroy(A);
    if (y) N_VDestroy(y);
    if (ctx) SUNContext_Free(&ctx);
  }
};

void check(int flag, const char* what) {
  if (flag < 0) throw std::runtime_error(std::string("integrate_bdf: ") + what + " failed (flag " + std::to_string(flag) + ")");
}

std::string flag_text(int flag) {
  char* name = CVodeGetReturnFlagName(flag);
  std::string s = name ? name : "unknown";
  std::free(name);
  switch (flag) {
    case CV_TOO_MUCH_WORK: return s + ": more than max_steps internal steps (hint: raise integrator.max_steps)";
    case CV_TOO_MUCH_ACC: return s + ": the tolerances cannot be met in floating point (hint: larger rtol/atol)";
    case CV_ERR_FAILURE: return s + ": the error test failed repeatedly or at the minimum step";
    case CV_CONV_FAILURE: return s + ": the Newton iteration failed repeatedly or at the minimum step";
    default: return s;
  }
}

void validate(const BdfOptions& o, double t0, const Eigen::VectorXd& x0, const std::vector<double>& outputs) {
  auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (!positive(o.rtol)) throw Error("integrator.rtol: expected a finite number > 0, got " + fmt(o.rtol));
  if (!positive(o.atol)) throw Error("integrator.atol: expected a finite number > 0, got " + fmt(o.atol));
  if (o.max_order < 1 || o.max_order > 5) throw Error("integrator.max_order: expected 1 to 5, got " + std::to_string(o.max_order));
  if (o.max_steps < 1) throw Error("integrator.max_steps: expected a whole number >= 1");
  for (const double h : {o.initial_step, o.min_step, o.max_step})
    if (!(std::isfinite(h) && h >= 0)) throw Error("integrator: step bounds must be finite and >= 0, got " + fmt(h));
  if (o.max_step > 0 && o.min_step > o.max_step) throw Error("integrator: min_step is larger than max_step");
  if (!std::isfinite(t0) || !x0.allFinite()) throw Error("integrate_bdf: the initial time and state must be finite");
  double last = t0;
  for (const double t : outputs) {
    if (!(std::isfinite(t) && t > last)) throw Error("integrate_bdf: output times must be finite and increasing after t0");
    last = t;
  }
}

}  // namespace

BdfResult integrate_bdf(const BdfRhs& f, const BdfJacobian& jac, double t0, const Eigen::VectorXd& x0,
                        const std::vector<double>& outputs, const BdfOptions& o) {
  if (!f || !jac) throw Error("integrate_bdf: a right-hand side and its exact Jacobian are required");
  validate(o, t0, x0, outputs);
  const auto n = static_cast<sunindextype>(x0.size());
  Callbacks cb{f, jac, x0, Eigen::VectorXd(x0.size()), Eigen::MatrixXd(x0.size(), x0.size()), {}};
  Cvode cv;
  check(SUNContext_Create(nullptr, &cv.ctx), "SUNContext_Create");
  cv.y = N_VNew_Serial(n, cv.ctx);
  if (!cv.y) throw std::bad_alloc();
  view(cv.y) = x0;
  cv.mem = CVodeCreate(CV_BDF, cv.ctx);
  if (!cv.mem) throw std::bad_alloc();
  check(CVodeSetErrHandlerFn(cv.mem, quiet, nullptr), "CVodeSetErrHandlerFn");
  check(CVodeInit(cv.mem, rhs, t0, cv.y), "CVodeInit");
  check(CVodeSStolerances(cv.mem, o.rtol, o.atol), "CVodeSStolerances");
  check(CVodeSetUserData(cv.mem, &cb), "CVodeSetUserData");
  cv.A = SUNDenseMatrix(n, n, cv.ctx);
  cv.LS = SUNLinSol_Dense(cv.y, cv.A, cv.ctx);
  if (!cv.A || !cv.LS) throw std::bad_alloc();
  check(CVodeSetLinearSolver(cv.mem, cv.LS, cv.A), "CVodeSetLinearSolver");
  check(CVodeSetJacFn(cv.mem, jacobian), "CVodeSetJacFn");
  check(CVodeSetMaxOrd(cv.mem, o.max_order), "CVodeSetMaxOrd");
  check(CVodeSetMaxNumSteps(cv.mem, o.max_steps), "CVodeSetMaxNumSteps");
  if (o.initial_step > 0) check(CVodeSetInitStep(cv.mem, o.initial_step), "CVodeSetInitStep");
  if (o.min_step > 0) check(CVodeSetMinStep(cv.mem, o.min_step), "CVodeSetMinStep");
  if (o.max_step > 0) check(CVodeSetMaxStep(cv.mem, o.max_step), "CVodeSetMaxStep");
  if (outputs.size()) check(CVodeSetStopTime(cv.mem, outputs.back()), "CVodeSetStopTime");

  BdfResult r;
  r.t.push_back(t0);
  r.x.push_back(x0);
  r.ok = true;
  for (const double tout : outputs) {
    sunrealtype treached = 0;
    const int flag = CVode(cv.mem, tout, cv.y, &treached, CV_NORMAL);
    if (flag < 0) {
      r.ok = false;
      r.message = cb.error.empty() ? flag_text(flag) + " at t = " + fmt(treached)
                                   : "the right-hand side or its Jacobian failed at t = " + fmt(treached) + ": " + cb.error;
      break;
    }
    r.t.push_back(tout);
    r.x.push_back(view(cv.y));
  }
  BdfCounters& k = r.counters;
  long v = 0;
  CVodeGetNumSteps(cv.mem, &v), k.steps = v;
  CVodeGetNumRhsEvals(cv.mem, &v), k.rhs_evaluations = v;
  CVodeGetNumJacEvals(cv.mem, &v), k.jacobian_evaluations = v;
  CVodeGetNumNonlinSolvIters(cv.mem, &v), k.newton_iterations = v;
  CVodeGetNumNonlinSolvConvFails(cv.mem, &v), k.newton_failures = v;
  CVodeGetNumErrTestFails(cv.mem, &v), k.error_test_failures = v;
  int q = 0;
  CVodeGetLastOrder(cv.mem, &q), k.last_order = q;
  sunrealtype h = 0;
  CVodeGetLastStep(cv.mem, &h), k.last_step = h;
  return r;
}

}  // namespace refdyn
