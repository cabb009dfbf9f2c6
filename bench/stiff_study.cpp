// The stiff-friction study (bench/README.md, "Stiff friction"): the paper's plan with LuGre
// bristles of stiffness σ0 in all three joints (σ1 = 300 for σ0 ≥ 1e3, the paper's soft values
// otherwise), integrated by RK4 at its largest stable step, by Dormand–Prince and by BDF.
//
//   stiff_study            the table for σ0 ∈ {5, 1e3, 1e5, 1e7} and the accuracy race at σ0 = 1e5
//   stiff_study --quick    σ0 ∈ {5, 1e3} only (a smoke run)
//
// Accuracy race: a reference plan by BDF with rtol 1e-12 is checked against Dormand–Prince with
// rtol 1e-12 (they must agree to 1e-8 in q); then each method runs at the loosest of a ladder of
// tolerances that stays within 1e-6 of the reference in q at every output sample, and the wall
// times are compared (one process, one after the other, best of three for the fast runs).
#include "refdyn/models/paper_example.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/simulate/plan.hpp"
#include "refdyn/simulate/stability.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

using namespace refdyn;

namespace {

struct Case {
  double sigma0, sigma1;
};

models::PaperExampleParams params(const Case& c) {
  models::PaperExampleParams p;
  p.lugre_rot.sigma0 = p.lugre_lin.sigma0 = c.sigma0;
  p.lugre_rot.sigma1 = p.lugre_lin.sigma1 = c.sigma1;
  return p;
}

struct Result {
  Plan plan;
  double wall = 0;
};

Result run(const Case& c, IntegratorOptions o, long max_steps = 50'000'000) {
  models::PaperExample ex(params(c));
  ReferenceDynamics rd(ex.model, ex.forces, ex.constraints, ex.options());
  o.max_steps = max_steps;
  RecordOptions rec;
  rec.residual_tolerance = std::numeric_limits<double>::infinity();
  const auto t0 = std::chrono::steady_clock::now();
  Result r;
  r.plan = plan_motion(rd, rd.make_state(ex.q0(), Eigen::VectorXd::Zero(3)), {o, 0.0, rec});
  r.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

IntegratorOptions method(IntegratorMethod m, double rtol, double out = 0.01) {
  IntegratorOptions o;
  o.method = m;
  o.t1 = 5.0;
  o.step = out;  // output interval (Dormand–Prince: also its first step)
  o.rtol = rtol;
  o.atol = rtol * 1e-2;
  o.min_step = 1e-14;
  return o;
}

/// Largest |q − q_ref| over the common output samples (both sampled every 0.01 s).
double q_error(const Plan& a, const Plan& ref) {
  double e = 0;
  const size_t k = std::min(a.x.size(), ref.x.size());
  for (size_t i = 0; i < k; ++i) e = std::max(e, (a.x[i].head(3) - ref.x[i].head(3)).cwiseAbs().maxCoeff());
  if (a.x.size() != ref.x.size()) e = std::numeric_limits<double>::infinity();
  return e;
}

/// RK4's largest stable step over the reference trajectory (the smallest over its samples).
double rk4_stable_step(const Case& c, const Plan& ref) {
  models::PaperExample ex(params(c));
  ReferenceDynamics rd(ex.model, ex.forces, ex.constraints, ex.options());
  double h = 0.01;
  Eigen::MatrixXd J;
  for (size_t i = 0; i < ref.x.size(); i += 5) {
    rd.jacobian(ref.t[i], ref.x[i], J);
    h = std::min(h, rk4_step_stability(J, h).largest_stable_step);
  }
  return h;
}

void row(const char* name, const Case& c, const Result& r, const std::string& note) {
  const IntegrationSummary& s = r.plan.summary;
  std::printf("| %g | %s | %ld | %ld | %ld | %.3g | %s%s |\n", c.sigma0, name, s.steps, s.rhs_evaluations,
              s.jacobian_evaluations, r.wall, s.ok() ? "reached 5 s; " : "stopped: ", s.ok() ? note.c_str() : s.message.substr(0, 80).c_str());
}

}  // namespace

int main(int argc, char** argv) {
  const bool quick = argc > 1 && std::strcmp(argv[1], "--quick") == 0;
  std::vector<Case> cases = {{5.0, 0.025}, {1e3, 300}};
  if (!quick) cases.insert(cases.end(), {{1e5, 300}, {1e7, 300}});

  std::printf("| sigma0 | method | steps | RHS evaluations | Jacobian evaluations | wall time [s] | note |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  for (const Case& c : cases) {
    const Result bdf = run(c, method(IntegratorMethod::BDF, 1e-8));
    const Result ref = run(c, method(IntegratorMethod::BDF, 1e-12));
    const double h = rk4_stable_step(c, ref.plan);
    const double per_sample = std::ceil(0.01 / (0.9 * h)), steps = 500 * per_sample;  // a step dividing 0.01 s
    if (steps <= 2e7) {
      IntegratorOptions o = method(IntegratorMethod::RK4, 1e-8);
      o.step = 0.01 / per_sample;
      o.output_interval = 0.01;
      const Result rk4 = run(c, o);
      char note[96];
      std::snprintf(note, sizeof note, "h = %.3g s (0.9 x stable %.3g s); max |q - ref| %.2g", o.step, h,
                    q_error(rk4.plan, ref.plan));
      row("RK4", c, rk4, note);
    } else {
      std::printf("| %g | RK4 | %.3g | - | - | - | not run: the stable step %.3g s needs %.3g steps |\n", c.sigma0, steps, h,
                  steps);
    }
    const Result dp = run(c, method(IntegratorMethod::DormandPrince45, 1e-8), 5'000'000);
    char note[64];
    std::snprintf(note, sizeof note, "rtol 1e-8; max |q - ref| %.2g", q_error(dp.plan, ref.plan));
    row("DOPRI5", c, dp, note);
    std::snprintf(note, sizeof note, "rtol 1e-8; max |q - ref| %.2g", q_error(bdf.plan, ref.plan));
    row("BDF", c, bdf, note);
  }
  if (quick) return 0;

  // The accuracy race at σ0 = 1e5, σ1 = 300.
  const Case stiff{1e5, 300};
  std::printf("\nAccuracy race, sigma0 = 1e5, sigma1 = 300 (target: max |q - ref| <= 1e-6 at every 0.01 s sample)\n");
  const Result ref_bdf = run(stiff, method(IntegratorMethod::BDF, 1e-12));
  const Result ref_dp = run(stiff, method(IntegratorMethod::DormandPrince45, 1e-12), 100'000'000);
  std::printf("reference BDF rtol 1e-12: %ld steps, %.3g s; DOPRI5 rtol 1e-12: %ld steps, %.3g s; they differ by %.3g in q\n",
              ref_bdf.plan.summary.steps, ref_bdf.wall, ref_dp.plan.summary.steps, ref_dp.wall,
              q_error(ref_dp.plan, ref_bdf.plan));
  auto loosest = [&](IntegratorMethod m, int repeats) {
    Result best;
    double tol_used = 0;
    for (const double tol : {1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10}) {
      Result r = run(stiff, method(m, tol));
      if (!r.plan.summary.ok() || q_error(r.plan, ref_bdf.plan) > 1e-6) continue;
      for (int k = 1; k < repeats; ++k) r.wall = std::min(r.wall, run(stiff, method(m, tol)).wall);
      best = std::move(r);
      tol_used = tol;
      break;
    }
    std::printf("%s: loosest rtol within 1e-6: %g, %ld steps, %ld RHS, %ld Jacobians, %.4g s, max |q - ref| %.3g\n",
                to_string(m), tol_used, best.plan.summary.steps, best.plan.summary.rhs_evaluations,
                best.plan.summary.jacobian_evaluations, best.wall, q_error(best.plan, ref_bdf.plan));
    return best.wall;
  };
  const double t_bdf = loosest(IntegratorMethod::BDF, 3);
  const double t_dp = loosest(IntegratorMethod::DormandPrince45, 1);
  std::printf("DOPRI5 / BDF wall time at the same accuracy: %.1f x\n", t_dp / t_bdf);
  return 0;
}
