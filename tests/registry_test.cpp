// Registries of constraint kinds, force elements and controllers: every entry documented (and the
// docs/scenario.md reference generated from them is current), unknown names answered with "did
// you mean", and the kind added as one file (distance) checked against finite differences and a
// closed-form motion. The scenario sections' declarations (scenario/schema.hpp): documented,
// their tables in docs/scenario.md current, their defaults those of a built problem.
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/optimize/optimize.hpp"
#include "refdyn/scenario/registry.hpp"
#include "refdyn/scenario/schema.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numbers>
#include <set>
#include <sstream>

using namespace refdyn;

namespace {

std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// A planar 2R arm in the horizontal plane with equal links L = 0.5 and points B (base) and E
// (tip): |E − B| = 2 L cos(q2/2).
std::string two_link(const std::string& constraint, const std::string& q0) {
  return R"(name: two_link
parameters: {L: 0.5, d0: 0.8, dd: 0.15, T: 2}
model:
  gravity: [0, 0, -9.81]
  links:
    - {name: l1, joint: q1, parent: base, type: revolute, axis: [0, 0, 1], mass: 1, com: [0.25, 0, 0], inertia: [0.001, 0.02, 0.02]}
    - {name: l2, joint: q2, parent: l1, type: revolute, axis: [0, 0, 1], origin: {xyz: [0.5, 0, 0]}, mass: 1, com: [0.25, 0, 0], inertia: [0.001, 0.02, 0.02]}
  points:
    B: {link: world, position: [0, 0, 0]}
    E: {link: l2, position: [0.5, 0, 0]}
constraints:
)" + constraint + R"(
partition: {independent: [q1]}
initial: {q: )" + q0 + R"(}
integrator: {method: rk4, step: 1e-3, t1: 2}
)";
}

}  // namespace

TEST(Registry, EveryEntryIsDocumentedAndTheScenarioReferenceIsCurrent) {
  for (const auto& k : constraint_kinds().entries()) {
    EXPECT_FALSE(k.doc.empty()) << k.name;
    EXPECT_TRUE(k.build) << k.name;
    for (const auto& key : k.keys) EXPECT_FALSE(key.doc.empty()) << k.name << "." << key.name;
  }
  for (const auto& k : force_kinds().entries()) EXPECT_FALSE(k.doc.empty()) << k.name;
  for (const auto& k : controller_kinds().entries()) EXPECT_FALSE(k.doc.empty()) << k.name;
  EXPECT_NE(constraint_kinds().find("distance"), nullptr);
  EXPECT_NE(controller_kinds().find("pid_gravity"), nullptr);
  const std::string doc = read_text(std::string(REFDYN_SOURCE_DIR) + "/docs/scenario.md");
  EXPECT_NE(doc.find(registry_markdown()), std::string::npos)
      << "docs/scenario.md does not contain the current registry reference; regenerate it with `refdyn kinds`";
}

TEST(Registry, UnknownNamesAreAnsweredWithDidYouMean) {
  test::expect_error_mentioning([] { constraint_kinds().get("distanse"); }, {"unknown constraint kind 'distanse'", "'distance'"});
  test::expect_error_mentioning([] { force_kinds().get("lugr"); }, {"'lugre'"});
  test::expect_error_mentioning([] { controller_kinds().get("pid_gravty"); }, {"'pid_gravity'"});
  test::expect_error_mentioning(
      [] { io::parse_scenario(two_link("  - {name: c, kind: distanse, points: [B, E], length: d0}", "[0, 1]"), "k.yaml"); },
      {"k.yaml:", "constraints.c.kind", "did you mean 'distance'"});
  test::expect_error_mentioning(
      [] { io::parse_scenario(two_link("  - {name: c, kind: distance, points: [B, E], lenght: d0}", "[0, 1]"), "k.yaml"); },
      {"k.yaml:", "constraints[0].lenght", "did you mean 'length'"});
}

// Φ, Φ̇, A and γ of the distance kind against central finite differences (in the test only),
// on a random spatial chain with the two points on different links.
TEST(DistanceKind, DerivativesMatchFiniteDifferences) {
  std::mt19937 rng(7);
  test::RandomChainOptions opt;
  opt.dof = 5;
  ModelDescription d = test::random_chain(rng, opt);
  d.add_point("P", d.links[1].name, Vec3(0.1, -0.05, 0.2));
  const Model m = build_model(d);
  SpecReader reader("test", {});
  EntrySpec e;
  e.kind = "distance";
  e.name = "rod";
  e.key = "constraints.rod";
  e.fields.kind = SpecValue::Kind::Map;
  SpecValue pts;
  pts.kind = SpecValue::Kind::List;
  pts.items = {SpecValue::scalar("P"), SpecValue::scalar("tip")};
  e.fields.entries = {{"points", 1, pts}, {"length", 1, SpecValue::scalar("0.7 + 0.1*sin(3*t)")}};
  ConstraintSet set;
  set.add(constraint_kinds().get("distance").build(EntryArgs{reader, e, m}, ConstraintOrigin::Programmed));
  Data data(m);
  ConstraintEval ev(m, set);
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd q = test::random_vector(rng, m.nq), qd = test::random_vector(rng, m.nq);
    const double t = 0.3 + 0.1 * trial, h = 1e-6;
    auto phi = [&](const Eigen::VectorXd& qq, double tt) {
      evaluate_constraints(m, data, set, ev, tt, qq, qd);
      return ev.phi[0];
    };
    auto phid = [&](const Eigen::VectorXd& qq, double tt) {
      evaluate_constraints(m, data, set, ev, tt, qq, qd);
      return ev.phid[0];
    };
    evaluate_constraints(m, data, set, ev, t, q, qd);
    const Eigen::MatrixXd A = ev.A;
    const double phid0 = ev.phid[0], gamma0 = ev.gamma[0];
    Eigen::RowVectorXd A_fd(m.nq);
    for (int j = 0; j < m.nq; ++j) {
      Eigen::VectorXd dq = Eigen::VectorXd::Zero(m.nq);
      dq[j] = h;
      A_fd[j] = (phi(q + dq, t) - phi(q - dq, t)) / (2 * h);
    }
    EXPECT_TRUE(test::near(A, A_fd, 1e-7, 1e-8)) << "A, trial " << trial;
    EXPECT_NEAR(phid0, (phi(q + h * qd, t + h) - phi(q - h * qd, t - h)) / (2 * h), 1e-7) << "phid, trial " << trial;
    // γ = Φ̈ at q̈ = 0: the rate of Φ̇ along (q̇, t).
    EXPECT_NEAR(gamma0, (phid(q + h * qd, t + h) - phid(q - h * qd, t - h)) / (2 * h), 1e-6) << "gamma, trial " << trial;
  }
}

// The distance between base and tip of an equal-link 2R arm prescribes the elbow angle:
// d(t) = 2 L cos(q2/2), so q2(t) = 2 acos(d(t)/(2L)) whatever the shoulder does.
TEST(DistanceKind, ElbowFollowsTheClosedFormOfAPrescribedReach) {
  const double L = 0.5, d0 = 0.8, dd = 0.15, T = 2;
  const double q20 = 2 * std::acos(d0 / (2 * L));
  const std::string c = "  - {name: reach, kind: distance, points: [B, E], length: d0 + dd*(1 - cos(2*pi*t/T))/2, record: d}";
  char q0[64];
  std::snprintf(q0, sizeof q0, "[0.3, %.17g]", q20);
  const auto p = io::parse_problem(two_link(c, q0), "reach.yaml");
  auto rd = p->make_reference_dynamics();
  const Plan plan = plan_problem(*p, *rd);
  ASSERT_TRUE(plan.summary.ok()) << plan.summary.message;
  ASSERT_EQ(plan.target_signals, std::vector<std::string>{"d"});
  double worst = 0;
  for (size_t k = 0; k < plan.size(); ++k) {
    const double t = plan.t[k];
    const double d = d0 + dd * (1 - std::cos(2 * std::numbers::pi * t / T)) / 2;
    EXPECT_NEAR(plan.targets[k][0], d, 1e-15);
    worst = std::max(worst, std::abs(plan.x[k][1] - 2 * std::acos(d / (2 * L))));
  }
  EXPECT_LT(worst, 1e-8) << "q2(t) differs from 2 acos(d(t)/2L)";
}

TEST(DistanceKind, CoincidingPointsAreReportedNotDividedBy) {
  // Folded arm: E on the base when q2 = π; the distance has no direction there.
  test::expect_error_mentioning(
      [] {
        io::parse_problem(two_link("  - {name: reach, kind: distance, points: [B, E], length: 0}", "[0, pi]"), "fold.yaml");
      },
      {"fold.yaml", "coincide"});
}

namespace {

/// A declared default as a number.
double declared(const char* section, const char* key) {
  const std::string& t = schema::key(section, key).default_text;
  size_t used = 0;
  double v = std::nan("");
  try {
    v = std::stod(t, &used);
  } catch (const std::exception&) {
  }
  EXPECT_EQ(used, t.size()) << section << "." << key << ": default '" << t << "' is not a number";
  return v;
}

}  // namespace

TEST(Schema, EveryKeyIsDocumentedOnceAndTheScenarioTablesAreCurrent) {
  std::set<std::string> paths;
  for (const schema::Section& s : schema::sections()) {
    EXPECT_TRUE(paths.insert(s.path).second) << "section '" << s.path << "' declared twice";
    EXPECT_FALSE(s.doc.empty()) << s.path;
    std::set<std::string> names;
    for (const schema::Key& k : s.keys) {
      EXPECT_TRUE(names.insert(k.name).second) << s.path << "." << k.name << " declared twice";
      EXPECT_FALSE(k.doc.empty()) << s.path << "." << k.name;
      EXPECT_FALSE(k.type.empty()) << s.path << "." << k.name;
      EXPECT_TRUE(k.required.empty() || k.default_text.empty())
          << s.path << "." << k.name << ": a required key has no default";
      if (!k.choices.empty() && !k.default_text.empty())
        EXPECT_NE(std::find(k.choices.begin(), k.choices.end(), k.default_text), k.choices.end())
            << s.path << "." << k.name << ": the default is not one of its choices";
    }
  }
  const std::string doc = read_text(std::string(REFDYN_SOURCE_DIR) + "/docs/scenario.md");
  EXPECT_NE(doc.find(schema::markdown()), std::string::npos)
      << "docs/scenario.md does not contain the current key tables; regenerate them with `refdyn kinds --sections`";
  EXPECT_THROW(schema::keys("integrater"), std::logic_error);
  EXPECT_THROW(schema::key("integrator", "stepp"), std::logic_error);
}

TEST(Schema, TheDeclaredDefaultsAreThoseOfABuiltProblem) {
  // Every optional section absent: what build_problem takes is what the tables say.
  auto p = io::parse_problem(R"(name: bare
model:
  links:
    - {name: l1, joint: q1, parent: base, type: revolute, axis: [0, 1, 0], mass: 1, com: [0.5, 0, 0], inertia: [0.01, 0.1, 0.1]}
initial: {q: [0.1]}
)", "bare.yaml");
  EXPECT_EQ(p->options.alpha, declared("baumgarte", "alpha"));
  EXPECT_EQ(p->options.beta, declared("baumgarte", "beta"));
  EXPECT_EQ(p->options.beta_first_order, declared("baumgarte", "beta_first_order"));
  EXPECT_EQ(p->kappa, declared("baumgarte", "kappa"));
  EXPECT_EQ(p->options.stabilization, Stabilization::Baumgarte);
  EXPECT_EQ(schema::key("stabilization", "method").required, "yes");  // the top-level default instead
  EXPECT_EQ(schema::key("", "stabilization").default_text, to_string(Stabilization::Baumgarte));
  EXPECT_EQ(p->options.projection_tolerance, declared("stabilization", "tolerance"));
  EXPECT_EQ(p->options.projection_max_iterations, declared("stabilization", "max_iterations"));
  EXPECT_EQ(p->options.automatic_partition, schema::key("partition", "automatic_switch").default_text == "true");
  EXPECT_EQ(p->options.max_condition, declared("partition", "max_condition"));
  EXPECT_EQ(p->initial_tolerance, declared("initial", "tolerance"));
  EXPECT_EQ(p->integrator.method, IntegratorMethod::RK4);
  EXPECT_EQ(schema::key("integrator", "method").default_text, to_string(IntegratorMethod::RK4));
  EXPECT_EQ(p->integrator.step, declared("integrator", "step"));
  EXPECT_EQ(p->integrator.t0, declared("integrator", "t0"));
  EXPECT_EQ(p->integrator.t1, declared("integrator", "t1"));
  EXPECT_EQ(p->integrator.rtol, declared("integrator", "rtol"));
  EXPECT_EQ(p->integrator.atol, declared("integrator", "atol"));
  EXPECT_EQ(p->integrator.output_interval, declared("integrator", "output_interval"));
  EXPECT_EQ(p->integrator.max_order, declared("integrator", "max_order"));
  EXPECT_EQ(p->integrator.min_step, std::min(1e-12, 0.5 * p->integrator.step));
  EXPECT_EQ(schema::key("integrator", "min_step").default_text, "min(1e-12, step/2)");
  EXPECT_EQ(p->residual_from, declared("integrator", "residual_from"));
  EXPECT_EQ(p->residual_tolerance, declared("integrator", "residual_tolerance"));
  EXPECT_EQ(p->limits.max_steps, declared("limits", "max_steps"));
  EXPECT_EQ(p->limits.max_samples, declared("limits", "max_samples"));
  EXPECT_EQ(p->limits.max_runs, declared("limits", "max_runs"));
  const ScenarioSpec spec;
  EXPECT_EQ(spec.solver, schema::key("", "solver").default_text);
  EXPECT_EQ(spec.paper_literal_forces, schema::key("", "paper_literal_forces").default_text == "true");
  EXPECT_EQ(OptimizeSpec{}.method, schema::key("optimize", "method").default_text);
  const OptimizeSetup o;
  EXPECT_EQ(std::string(to_string(o.method)), schema::key("optimize", "method").default_text);
  EXPECT_EQ(o.xtol, declared("optimize.tolerance", "x"));
  EXPECT_EQ(o.ftol, declared("optimize.tolerance", "f"));
  EXPECT_EQ(o.budget, declared("optimize", "budget"));
  EXPECT_EQ(o.feasible, schema::key("optimize.constraints", "feasible").default_text == "true");
}

TEST(Schema, TheReaderRefusesAKeyNoSectionDeclares) {
  // One misspelt key per section read by hand: the message names the section's path and the
  // declared key it resembles.
  const std::string base = R"(name: bare
model:
  links:
    - {name: l1, joint: q1, parent: base, type: revolute, axis: [0, 1, 0], mass: 1, com: [0.5, 0, 0], inertia: [0.01, 0.1, 0.1]}
)";
  const std::vector<std::pair<std::string, std::string>> cases{
      {"initial: {q: [0.1], toleranse: 1}\n", "initial.toleranse: unknown key 'toleranse' (did you mean 'tolerance'?)"},
      {"initial: {q: [0.1]}\nintegrator: {stepp: 1}\n", "integrator.stepp: unknown key 'stepp' (did you mean 'step'?)"},
      {"initial: {q: [0.1]}\nlimits: {max_step: 1}\n", "limits.max_step: unknown key 'max_step' (did you mean 'max_steps'?)"},
      {"initial: {q: [0.1]}\ntime_law: {task_duraton: 1}\n",
       "time_law.task_duraton: unknown key 'task_duraton' (did you mean 'task_duration'?)"},
      {"initial: {q: [0.1]}\nintegrater: {}\n", "integrater: unknown key 'integrater' (did you mean 'integrator'?)"},
  };
  // (pairs by member: clang 14 cannot capture a structured binding in a lambda)
  for (const auto& c : cases)
    test::expect_error_mentioning([&] { io::parse_scenario(base + c.first, "bare.yaml"); }, {c.second});
  // The model section (read when the problem is built) and a Monte Carlo distribution.
  const std::string link = "{name: l1, joint: q1, parent: base, type: revolute, axis: [0, 1, 0], mass: 1}";
  const std::vector<std::pair<std::string, std::string>> built{
      {"model:\n  gravty: [0, 0, -9.81]\n  links:\n    - " + link + "\ninitial: {q: [0.1]}\n",
       "model.gravty: unknown key 'gravty' (did you mean 'gravity'?)"},
      {"model:\n  links:\n    - {name: l1, typ: revolute}\ninitial: {q: [0.1]}\n",
       "model.links[0].typ: unknown key 'typ' (did you mean 'type'?)"},
      {"model:\n  links:\n    - {name: l1, type: revolute, limits: {lowr: -1}}\ninitial: {q: [0.1]}\n",
       "model.links[0].limits.lowr: unknown key 'lowr' (did you mean 'lower'?)"},
      {"model:\n  dh:\n    joints:\n      - {name: q1, type: revolute, alpah: 0}\ninitial: {q: [0.1]}\n",
       "model.dh.joints[0].alpah: unknown key 'alpah' (did you mean 'alpha'?)"},
      {"model:\n  links:\n    - " + link + "\n  points: {E: {link: l1, positon: [1, 0, 0]}}\ninitial: {q: [0.1]}\n",
       "model.points.E.positon: unknown key 'positon' (did you mean 'position'?)"},
      {"model:\n  links:\n    - " + link + "\ninitial: {q: [0.1]}\ncontroller: {type: pd_gravity, kp: 1, kd: 1}\n"
       "experiments:\n  - {name: mc, monte_carlo: {samples: 2, seed: 1, distributions: {m: {normall: {mean: 1, std: 0}}}}}\n",
       "unknown distribution 'normall' (did you mean 'normal'?)"},
      {"model:\n  links:\n    - " + link + "\ninitial: {q: [0.1]}\ncontroller: {type: pd_gravity, kp: 1, kd: 1}\n"
       "experiments:\n  - {name: mc, monte_carlo: {samples: 2, seed: 1, distributions: {m: {uniform: {low: 0, hihg: 1}}}}}\n",
       "uniform.hihg: unknown key 'hihg' (did you mean 'high'?)"},
  };
  for (const auto& c : built)
    test::expect_error_mentioning([&] { io::parse_problem("name: bare\n" + c.first, "bare.yaml"); }, {c.second});
}

TEST(Schema, TheChoiceWordsAreTheEnumsNames) {
  // integrator.method: every enumerator's name, in order, and nothing else.
  std::vector<std::string> methods;
  for (IntegratorMethod m : {IntegratorMethod::RK4, IntegratorMethod::DormandPrince45, IntegratorMethod::BDF})
    methods.push_back(to_string(m));
  EXPECT_EQ(schema::choices("integrator", "method"), methods);
  for (const std::string& w : schema::choices("integrator", "method")) {
    IntegratorMethod m{};
    EXPECT_TRUE(from_string(w, m)) << w;
  }
  std::vector<std::string> optimizers;
  for (OptimizeMethod m : {OptimizeMethod::Slsqp, OptimizeMethod::Mma, OptimizeMethod::Cobyla, OptimizeMethod::Bobyqa,
                           OptimizeMethod::PhasePlane})
    optimizers.push_back(to_string(m));
  EXPECT_EQ(schema::choices("optimize", "method"), optimizers);
  std::vector<std::string> stabilizations;
  for (Stabilization s : {Stabilization::Baumgarte, Stabilization::Projection, Stabilization::Both})
    stabilizations.push_back(to_string(s));
  EXPECT_EQ(schema::choices("stabilization", "method"), stabilizations);
}
