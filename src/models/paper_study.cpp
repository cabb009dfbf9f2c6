#include "refdyn/models/paper_study.hpp"

#include "refdyn/common/error.hpp"

#include <cmath>
#include <numbers>

namespace refdyn::models {

PaperStudy run_paper_study(const PaperStudyOptions& o) {
  PaperStudy s;
  s.options = o;
  s.example = std::make_unique<PaperExample>(o.example);
  PaperExample& ex = *s.example;
  s.rd = std::make_unique<ReferenceDynamics>(ex.model, ex.forces, ex.constraints, ex.options());
  const Eigen::VectorXd x0 = s.rd->make_state(ex.q0(), Eigen::VectorXd::Zero(ex.model.nv));
  s.plan = plan_motion(*s.rd, x0, {ex.integrator(), 0.5});

  s.plant_friction.add(std::make_shared<LuGreFriction>(ex.model, "psi1", o.example.lugre_rot));
  s.plant_friction.add(std::make_shared<LuGreFriction>(ex.model, "psi2", o.example.lugre_rot));
  s.plant_friction.add(std::make_shared<LuGreFriction>(ex.model, "z3", o.example.lugre_lin));
  const ForceSet no_forces;

  ClosedLoopOptions clo;
  clo.integrator = ex.integrator();
  clo.effort_limit = o.effort_limit;
  for (bool friction : o.plant_friction) {
    for (double a0 : o.alpha0_deg) {
      if (!std::isfinite(a0)) throw Error("paper study: initial angles must be finite");
      PaperStudyRun run;
      run.alpha0_deg = a0;
      run.plant_friction = friction;
      run.label = "a" + std::to_string(static_cast<int>(std::lround(a0))) + (friction ? "_friction" : "_nofriction");
      const ForceSet& pf = friction ? s.plant_friction : no_forces;
      Eigen::VectorXd xp = Eigen::VectorXd::Zero(2 * ex.model.nv + pf.num_states());
      xp[0] = 0.0;
      xp[1] = 1.5 * std::numbers::pi - a0 * std::numbers::pi / 180.0;
      xp[2] = o.example.z3_0;
      ComputedTorquePD ctrl(ex.model, o.delta);
      run.result = simulate_closed_loop(ex.model, pf, ctrl, s.plan, s.rd.get(), xp, clo);
      s.runs.push_back(std::move(run));
    }
  }
  return s;
}

}  // namespace refdyn::models
