#include "refdyn/simulate/integrators.hpp"

#include "bdf.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/common/text.hpp"

#include <boost/numeric/odeint.hpp>
#include <boost/numeric/odeint/external/eigen/eigen.hpp>
#include <chrono>
#include <cmath>
#include <limits>

namespace refdyn {

const char* to_string(IntegratorMethod m) {
  switch (m) {
    case IntegratorMethod::RK4: return "rk4";
    case IntegratorMethod::DormandPrince45: return "dopri5";
    case IntegratorMethod::BDF: return "bdf";
  }
  return "?";
}

bool from_string(const std::string& text, IntegratorMethod& m) {
  for (const IntegratorMethod k : {IntegratorMethod::RK4, IntegratorMethod::DormandPrince45, IntegratorMethod::BDF})
    if (text == to_string(k)) {
      m = k;
      return true;
    }
  return false;
}

const char* to_string(IntegrationStatus s) {
  switch (s) {
    case IntegrationStatus::Success: return "success";
    case IntegrationStatus::NonFinite: return "non-finite state";
    case IntegrationStatus::StepSizeCollapse: return "step-size collapse";
    case IntegrationStatus::NumericalFailure: return "numerical failure";
    case IntegrationStatus::MaxSteps: return "maximum number of steps";
    case IntegrationStatus::Stopped: return "stopped by observer";
    case IntegrationStatus::ResidualExceeded: return "residual above tolerance";
    case IntegrationStatus::ReferenceStopped: return "reference stopped early";
  }
  return "?";
}

bool from_string(const std::string& text, IntegrationStatus& s) {
  for (int k = 0; k <= static_cast<int>(IntegrationStatus::ReferenceStopped); ++k)
    if (text == to_string(static_cast<IntegrationStatus>(k))) {
      s = static_cast<IntegrationStatus>(k);
      return true;
    }
  return false;
}

void IntegratorOptions::validate() const {
  auto need = [](bool ok, const char* what, const std::string& expected, double got) {
    if (!ok) throw Error(expected_got(std::string("integrator option ") + what, expected, fmt(got)));
  };
  need(std::isfinite(t0), "t0", "a finite time", t0);
  need(std::isfinite(t1) && t1 > t0, "t1", "a finite time > t0 = " + fmt(t0), t1);
  need(std::isfinite(step) && step > 0, "step", "a finite value > 0 [s]", step);
  need(std::isfinite(output_interval) && output_interval >= 0, "output_interval", "a finite value >= 0 [s]",
       output_interval);
  need(rtol > 0 && std::isfinite(rtol), "rtol", "a finite value > 0", rtol);
  need(atol > 0 && std::isfinite(atol), "atol", "a finite value > 0", atol);
  need(min_step > 0 && min_step < step, "min_step", "a value in (0, step)", min_step);
  need(max_steps > 0, "max_steps", "a positive count", static_cast<double>(max_steps));
  need(max_order >= 1 && max_order <= 5, "max_order", "a whole number from 1 to 5 (the BDF order)",
       static_cast<double>(max_order));
  const double span = t1 - t0;
  need(std::isfinite(span), "t1", "a time span t1 - t0 that is a finite number", span);
  // The step count must be a number the integrator can count to (1e-300 over 1e300 is not).
  const double steps = span / step;
  need(std::isfinite(steps) && steps < 9e15, "step", "a step giving a countable number of steps over [t0, t1]",
       step);
}

Rk4Grid::Rk4Grid(const IntegratorOptions& o) : t0_(o.t0), t1_(o.t1) {
  steps_ = std::lround(std::ceil((o.t1 - o.t0) / o.step - 1e-9));
  h_ = (o.t1 - o.t0) / steps_;  // exact landing on t1
  every_ = o.output_interval > 0 ? std::max(1L, std::lround(o.output_interval / h_)) : 1L;
  std::vector<double> b{o.t0};  // the parts' ends: the breakpoints inside (t0, t1), then t1
  for (double t : o.breakpoints)
    if (t > b.back() && t < o.t1) b.push_back(t);
  if (b.size() == 1) return;  // none: the uniform grid
  b.push_back(o.t1);
  for (size_t j = 0; j + 1 < b.size(); ++j) {
    const long n = std::max(1L, std::lround(std::ceil((b[j + 1] - b[j]) / o.step - 1e-9)));
    const double h = (b[j + 1] - b[j]) / static_cast<double>(n);
    for (long k = 0; k < n; ++k) {
      times_.push_back(b[j] + static_cast<double>(k) * h);
      steps_h_.push_back(h);
      parts_.push_back(static_cast<int>(j));
      ends_on_break_.push_back(k + 1 == n && j + 2 < b.size());
    }
  }
  times_.push_back(o.t1);
  steps_ = static_cast<long>(steps_h_.size());
  samples_.assign(steps_h_.size(), o.output_interval > 0 ? 0 : 1);
  if (o.output_interval > 0) {
    double next = o.t0 + o.output_interval;
    for (size_t k = 0; k < steps_h_.size(); ++k) {
      const double t = times_[k + 1];
      if (t >= next - 1e-9 * steps_h_[k] || k + 1 == steps_h_.size()) {
        samples_[k] = 1;
        while (next <= t + 1e-9 * steps_h_[k]) next += o.output_interval;
      }
    }
  }
}

double Rk4Grid::stage_time(long k, double c) const {
  // The last stage (c = 1) is at the step's end as the grid holds it, never start + h rounded past
  // it: past t1 a time law is at rest (TimeLaw::eval), so a last stage at t1 + 1 ulp saw s̈ = 0
  // instead of the final deceleration (measured: +3.3 % effort at the last sample of the 8-part
  // rotor, tests/phase_plane_test.cpp, RotorBangBangMatchesTheClosedForm).
  if (times_.empty()) {
    const double t = t0_ + k * h_ + c * h_;
    return c == 1.0 && k + 1 == steps_ ? std::min(t, t1_) : t;
  }
  const size_t u = static_cast<size_t>(k);
  if (c == 1.0)
    return ends_on_break_[u] ? std::nextafter(times_[u + 1], -std::numeric_limits<double>::infinity()) : end(k);
  return times_[u] + c * steps_h_[u];
}

Rk4Workspace::Rk4Workspace(Eigen::Index n) : k1(n), k2(n), k3(n), k4(n), tmp(n) {}

namespace {
// One RK4 step; f(stage, t, x, dx) with stage 0..3; the last stage at t_end (t + h, or the
// left limit at a breakpoint: Rk4Grid::stage_time).
template <class F>
void rk4_stages(const F& f, double t, double h, Eigen::VectorXd& x, Rk4Workspace& w, double t_end) {
  f(0, t, x, w.k1);
  w.tmp = x + (0.5 * h) * w.k1;
  f(1, t + 0.5 * h, w.tmp, w.k2);
  w.tmp = x + (0.5 * h) * w.k2;
  f(2, t + 0.5 * h, w.tmp, w.k3);
  w.tmp = x + h * w.k3;
  f(3, t_end, w.tmp, w.k4);
  x += (h / 6.0) * (w.k1 + 2.0 * w.k2 + 2.0 * w.k3 + w.k4);
}
}  // namespace

void rk4_step(const OdeRhs& f, double t, double h, Eigen::VectorXd& x, Rk4Workspace& w) {
  rk4_stages([&f](int, double tt, const Eigen::VectorXd& xx, Eigen::VectorXd& dx) { f(tt, xx, dx); }, t, h, x, w, t + h);
}

namespace {

IntegrationSummary integrate_rk4(const OdeStageRhs& f, Eigen::VectorXd& x, const IntegratorOptions& o,
                                 const OdeObserver& obs, const OdeProjection& projection) {
  IntegrationSummary s;
  const Rk4Grid grid(o);
  const long nsteps = grid.steps();
  Rk4Workspace w(x.size());
  Eigen::VectorXd x_prev = x;
  s.t_end = o.t0;
  if (obs && !obs(o.t0, x)) {
    s.status = IntegrationStatus::Stopped;
    s.message = "stopped by the observer at t = " + fmt(o.t0) + " s";
    return s;
  }
  for (long k = 0; k < nsteps; ++k) {
    if (k >= o.max_steps) {
      s.status = IntegrationStatus::MaxSteps;
      s.message = "stopped at t = " + fmt(s.t_end) + " s after max_steps = " + std::to_string(o.max_steps);
      return s;
    }
    const double t = grid.start(k), h = grid.size(k);
    x_prev = x;
    try {
      rk4_stages([&f, k](int stage, double tt, const Eigen::VectorXd& xx, Eigen::VectorXd& dx) {
        f(Stage{k, stage}, tt, xx, dx);
      }, t, h, x, w, grid.stage_time(k, 1.0));
    } catch (const NumericalFailure& e) {
      x = x_prev;
      s.status = IntegrationStatus::NumericalFailure;
      s.message = e.what();
      return s;
    }
    s.rhs_evaluations += 4;
    if (!x.allFinite()) {
      x = x_prev;
      s.status = IntegrationStatus::NonFinite;
      s.message = "the state became NaN or infinite in the step from t = " + fmt(t) + " s to " + fmt(t + h) +
                  " s (the run diverged; reduce the step or check the model)";
      return s;
    }
    ++s.steps;
    s.t_end = grid.end(k);
    if (projection) try {
        projection(s.t_end, x);
      } catch (const NumericalFailure& e) {
        s.status = IntegrationStatus::NumericalFailure;
        s.message = e.what();
        return s;
      }
    if (obs && grid.sample(k) && !obs(s.t_end, x)) {
      s.status = IntegrationStatus::Stopped;
      s.message = "stopped by the observer at t = " + fmt(s.t_end) + " s";
      return s;
    }
  }
  return s;
}

IntegrationSummary integrate_dopri(const OdeStageRhs& f, Eigen::VectorXd& x, const IntegratorOptions& o,
                                   const OdeObserver& obs, const OdeProjection& projection) {
  namespace ode = boost::numeric::odeint;
  using Stepper = ode::runge_kutta_dopri5<Eigen::VectorXd, double, Eigen::VectorXd, double, ode::vector_space_algebra>;
  IntegrationSummary s;
  long evals = 0;
  // The breakpoints inside (t0, t1) (IntegratorOptions::breakpoints): a step toward the next one
  // (`to_break`) ends on it and evaluates there at the double below it (the left limit); the
  // stepper restarts on it.
  std::vector<double> breaks;
  for (double b : o.breakpoints)
    if (b > o.t0 && b < o.t1 && (breaks.empty() || b > breaks.back())) breaks.push_back(b);
  size_t next_break = 0;
  bool to_break = false;
  // A stage time t + c·dt rounded past t1 on the last step is t1 (past it a time law is at rest:
  // Rk4Grid::stage_time).
  auto sys = [&](const Eigen::VectorXd& xx, Eigen::VectorXd& dx, double t) {
    ++evals;
    if (to_break && t >= breaks[next_break])
      t = std::nextafter(breaks[next_break], -std::numeric_limits<double>::infinity());
    else if (t > o.t1)
      t = o.t1;
    f(Stage{}, t, xx, dx);
  };
  auto stepper = ode::make_dense_output(o.atol, o.rtol, Stepper());
  const double dt_out = o.output_interval > 0 ? o.output_interval : o.step;
  s.t_end = o.t0;
  if (obs && !obs(o.t0, x)) {
    s.status = IntegrationStatus::Stopped;
    s.message = "stopped by the observer at t = " + fmt(o.t0) + " s";
    return s;
  }
  Eigen::VectorXd xs(x.size());
  long next_out = 1;
  try {
    stepper.initialize(x, o.t0, std::min(o.step, o.t1 - o.t0));
    while (stepper.current_time() < o.t1 - 1e-15 * std::max(1.0, std::abs(o.t1))) {
      if (s.steps >= o.max_steps) {
        s.status = IntegrationStatus::MaxSteps;
        s.message = "stopped at t = " + fmt(s.t_end) + " s after max_steps = " + std::to_string(o.max_steps);
        break;
      }
      if (stepper.current_time_step() < o.min_step) {
        s.status = IntegrationStatus::StepSizeCollapse;
        s.message = "the adaptive step fell to " + fmt(stepper.current_time_step()) + " s < min_step = " +
                    fmt(o.min_step) + " s at t = " + fmt(stepper.current_time()) +
                    " s (the solution is stiff or singular there)";
        break;
      }
      // Do not step past t1 or the next breakpoint: shrink the proposed step.
      const double bound = next_break < breaks.size() ? breaks[next_break] : o.t1;
      const double proposed = stepper.current_time_step();
      to_break = false;
      const double reach = stepper.current_time() + stepper.current_time_step();
      if (next_break < breaks.size() ? reach >= bound : reach > bound) {
        to_break = next_break < breaks.size();
        stepper.initialize(stepper.current_state(), stepper.current_time(), bound - stepper.current_time());
      }
      const long before = evals;
      auto span = stepper.do_step(sys);
      // On a breakpoint (up to rounding of t + h): there exactly, and the stepper restarts there
      // with the step it proposed before (its derivative at the breakpoint is the right limit).
      const bool landed = to_break && span.second >= bound - 1e-14 * std::max(1.0, std::abs(bound));
      to_break = false;
      if (landed) {
        span.second = bound;
        ++next_break;
      }
      const long used = evals - before;
      s.rejected_steps += std::max(0L, used / 6 - 1);
      if (!stepper.current_state().allFinite()) {
        s.status = IntegrationStatus::NonFinite;
        s.message = "the state became NaN or infinite between t = " + fmt(span.first) + " s and " +
                    fmt(span.second) + " s (the run diverged)";
        break;  // x still holds the last valid state

      }
      ++s.steps;
      bool stop = false;
      while (obs && !stop) {
        const double tout = std::min(o.t0 + next_out * dt_out, o.t1);
        if (tout > span.second + 1e-12 * dt_out) break;
        stepper.calc_state(tout, xs);
        stop = !obs(tout, xs);
        if (tout >= o.t1) break;
        ++next_out;
      }
      x = stepper.current_state();
      s.t_end = span.second;
      if (projection && !stop) {
        projection(s.t_end, x);  // a NumericalFailure is caught below
        stepper.initialize(x, s.t_end, landed ? proposed : stepper.current_time_step());
      } else if (landed) {
        stepper.initialize(x, s.t_end, proposed);
      }
      if (stop) {
        s.status = IntegrationStatus::Stopped;
        s.message = "stopped by the observer at t = " + fmt(s.t_end) + " s";
        break;
      }
    }
  } catch (const NumericalFailure& e) {
    s.status = IntegrationStatus::NumericalFailure;
    s.message = e.what();
    x = stepper.current_state();
  } catch (const ode::step_adjustment_error& e) {
    s.status = IntegrationStatus::StepSizeCollapse;
    s.message = std::string("the adaptive step could not be adjusted at t = ") + fmt(stepper.current_time()) +
                " s: " + e.what();
    x = stepper.current_state();
  }
  s.rhs_evaluations = evals;
  return s;
}

}  // namespace

IntegrationSummary integrate(const OdeRhs& f, Eigen::VectorXd& x, const IntegratorOptions& o,
                             const OdeObserver& observer, const OdeJacobian& jacobian,
                             const OdeProjection& projection) {
  if (!f) throw Error("integrate: expected a right-hand side function, got none");
  return integrate_staged([&f](const Stage&, double t, const Eigen::VectorXd& xx, Eigen::VectorXd& dx) { f(t, xx, dx); },
                          x, o, observer, jacobian, projection);
}

IntegrationSummary integrate_staged(const OdeStageRhs& f, Eigen::VectorXd& x, const IntegratorOptions& o,
                                    const OdeObserver& observer, const OdeJacobian& jacobian,
                                    const OdeProjection& projection) {
  o.validate();
  if (!f) throw Error("integrate: expected a right-hand side function, got none");
  if (o.method == IntegratorMethod::BDF && !jacobian)
    throw Error("integrate: method bdf needs the exact Jacobian of the right-hand side, got none (refdyn does not "
                "difference it numerically)");
  check_finite("initial state x0", x);
  const auto start = std::chrono::steady_clock::now();
  IntegrationSummary s = o.method == IntegratorMethod::RK4 ? integrate_rk4(f, x, o, observer, projection)
                         : o.method == IntegratorMethod::BDF
                             ? detail::integrate_bdf(f, jacobian, x, o, observer, projection)
                             : integrate_dopri(f, x, o, observer, projection);
  s.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return s;
}

}  // namespace refdyn
