// The pipeline: scenario text → ScenarioSpec (structure) → build_problem → run_problem →
// Trajectories and result files. Checked against independent routes: the built-in C++ paper
// study (bit for bit), a re-evaluation of the reference dynamics at every recorded sample, the
// closed-form steady state of PD and PID loops, and the integrators' stage order.
#include "refdyn/common/error.hpp"
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/models/paper_study.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

using namespace refdyn;
namespace fs = std::filesystem;

namespace {

std::string source_path(const std::string& rel) { return std::string(REFDYN_SOURCE_DIR) + "/" + rel; }

// A horizontal planar 2R arm (the minimal test scenario) with `extra` appended.
std::string arm(const std::string& extra) {
  return R"(name: arm
parameters: {L1: 0.5, L2: 0.4}
model:
  gravity: [0, 0, -9.81]
  dh:
    joints:
      - {name: j1, link: upper, type: revolute, a: L1, mass: 2, com: [-0.25, 0, 0], inertia: [0.01, 0.05, 0.05]}
      - {name: j2, link: lower, type: revolute, a: L2, mass: 1, com: [-0.2, 0, 0], inertia: [0.005, 0.02, 0.02]}
  points:
    E: {link: lower, position: [0, 0, 0]}
    O: {link: world, position: [0, 0, 0]}
initial:
  q: {j1: 0, j2: 90*deg}
integrator: {method: rk4, step: 1e-3, t0: 0, t1: 0.2}
)" + extra;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// The paper scenario through the pipeline equals the built-in C++ study, bit for bit.
TEST(Pipeline, PaperScenarioEqualsTheBuiltInStudyBitForBit) {
  const auto p = io::load_problem(source_path("examples/paper/paper.yaml"));
  io::RunOptions o;
  o.track = true;
  const io::Results r = io::run_problem(*p, o);
  const models::PaperStudy s = models::run_paper_study();
  ASSERT_TRUE(r.plan.summary.ok()) << r.plan.summary.message;
  ASSERT_EQ(r.plan.x.size(), s.plan.x.size());
  for (size_t k = 0; k < s.plan.x.size(); ++k) {
    ASSERT_EQ(r.plan.x[k], s.plan.x[k]) << "sample " << k;
    ASSERT_EQ(r.plan.qdd[k], s.plan.qdd[k]) << "sample " << k;
  }
  EXPECT_EQ(r.plan.summary.max_constraint_residual, s.plan.summary.max_constraint_residual);
  ASSERT_EQ(r.runs.size(), s.runs.size());
  for (size_t i = 0; i < s.runs.size(); ++i) {
    EXPECT_EQ(r.runs[i].experiment->name, s.runs[i].label);
    ASSERT_EQ(r.runs[i].result.x.size(), s.runs[i].result.x.size());
    for (size_t k = 0; k < s.runs[i].result.x.size(); ++k) {
      ASSERT_EQ(r.runs[i].result.x[k], s.runs[i].result.x[k]) << s.runs[i].label << " sample " << k;
      ASSERT_EQ(r.runs[i].result.tau[k], s.runs[i].result.tau[k]) << s.runs[i].label << " sample " << k;
    }
  }
  // What the plan table records beyond the state: z_a, the drive signals, the efforts.
  const Trajectory& t = r.plan;
  EXPECT_EQ(t.target_signals, std::vector<std::string>{"z_a"});
  EXPECT_EQ(t.force_signals, (std::vector<std::string>{"psi_dr", "tau_drive"}));
  EXPECT_TRUE(t.reaction_effort.empty()) << "the paper has no material constraints";
  for (size_t k = 0; k < t.size(); k += 250) {
    EXPECT_EQ(t.targets[k][0], s.example->z_a->eval(t.t[k]).f);
    const Eigen::VectorXd q = t.x[k].head(3), qd = t.x[k].segment(3, 3);
    EXPECT_EQ(t.forces[k][1], s.example->drive->torque(t.t[k], q, qd));
    Eigen::VectorXd expected = t.Qc[k];
    expected[0] += t.forces[k][1];
    EXPECT_EQ(t.actuator_effort[k], expected) << "required effort = Q_c + drive torque";
  }
}

// ---------------------------------------------------------------------------------------------
// Every recorded sample equals a fresh evaluation of the reference dynamics at that state, and
// the efforts split Q_c into the material reactions (−A_matᵀ λ_mat) and the rest.
TEST(Pipeline, RecordedSamplesEqualReEvaluationAndEffortsSplitQc) {
  const auto p = io::load_problem(source_path("examples/four_bar/four_bar.yaml"));
  auto rd = p->make_reference_dynamics();
  const Plan plan = plan_problem(*p, *rd);
  ASSERT_TRUE(plan.summary.ok()) << plan.summary.message;
  ASSERT_FALSE(plan.reaction_effort.empty()) << "the four-bar's loop closure is material";
  auto fresh = p->make_reference_dynamics();
  Eigen::VectorXd dx(fresh->state_size());
  const int n = p->model.nv;
  double worst_reaction = 0;
  for (size_t k = 0; k < plan.size(); k += 97) {
    fresh->derivative(plan.t[k], plan.x[k], dx);
    EXPECT_EQ(plan.qdd[k], dx.segment(n, n)) << k;
    EXPECT_EQ(plan.lambda[k], fresh->lambda()) << k;
    EXPECT_EQ(plan.Qc[k], fresh->constraint_force()) << k;
    EXPECT_EQ(plan.phi[k], fresh->constraints().phi) << k;
    Eigen::VectorXd reaction = Eigen::VectorXd::Zero(n);
    for (int row = 0; row < p->constraints.rows(); ++row)
      if (plan.material_row[row]) reaction -= fresh->constraints().A.row(row).transpose() * fresh->lambda()[row];
    EXPECT_TRUE(test::near(plan.reaction_effort[k], reaction, 1e-12, 1e-12)) << k;
    Eigen::VectorXd actuators = Eigen::VectorXd::Zero(n);
    for (size_t e = 0; e < p->forces.elements().size(); ++e)
      if (p->forces.elements()[e]->actuator())
        actuators += p->forces.element_force(static_cast<int>(e), plan.t[k], plan.x[k].head(n), plan.x[k].segment(n, n),
                                             plan.x[k].data() + 2 * n);
    EXPECT_TRUE(test::near(plan.actuator_effort[k] + plan.reaction_effort[k], plan.Qc[k] + actuators, 1e-12, 1e-12)) << k;
    // Only the crank is driven (its programmed trajectory): the passive coupler and rocker
    // deliver no effort, although the loop closure loads them.
    EXPECT_LT(plan.actuator_effort[k].tail(2).cwiseAbs().maxCoeff(), 1e-9) << k;
    worst_reaction = std::max(worst_reaction, plan.reaction_effort[k].tail(2).cwiseAbs().maxCoeff());
  }
  EXPECT_GT(worst_reaction, 0.1) << "the loop closure carries load in the passive joints";
}

// ---------------------------------------------------------------------------------------------
// The stage hook names RK4's stages in order, at t, t + h/2, t + h/2, t + h.
TEST(Pipeline, Rk4StageHookNamesEveryStage) {
  IntegratorOptions o;
  o.t0 = 0.5;
  o.t1 = 0.6;
  o.step = 0.025;
  std::vector<Stage> seen;
  std::vector<double> times;
  Eigen::VectorXd x(1);
  x << 1.0;
  const auto s = integrate_staged(
      [&](const Stage& st, double t, const Eigen::VectorXd& xx, Eigen::VectorXd& dx) {
        seen.push_back(st);
        times.push_back(t);
        dx = -xx;
      },
      x, o);
  ASSERT_TRUE(s.ok());
  ASSERT_EQ(seen.size(), 16u);
  const double off[4] = {0, 0.5, 0.5, 1};
  for (size_t i = 0; i < seen.size(); ++i) {
    EXPECT_EQ(seen[i].step, static_cast<long>(i / 4));
    EXPECT_EQ(seen[i].stage, static_cast<int>(i % 4));
    EXPECT_NEAR(times[i], 0.5 + 0.025 * (static_cast<double>(i / 4) + off[i % 4]), 1e-15);
  }
  EXPECT_NEAR(x[0], std::exp(-0.1), 1e-9);  // RK4 at h = 0.025: error ~ h^4
}

// ---------------------------------------------------------------------------------------------
// Controllers with states: the PID's integral is part of the closed-loop state and removes the
// steady error F/K_p that PD leaves under a constant disturbance force F.
TEST(Pipeline, PidIntegralRemovesTheSteadyErrorThatPdLeaves) {
  const std::string text = R"(name: slider
model:
  gravity: [0, 0, 0]
  links:
    - {name: cart, parent: base, type: prismatic, axis: [1, 0, 0], mass: 2, inertia: [0.01, 0.01, 0.01]}
initial: {q: {cart: 0}}
integrator: {method: rk4, step: 1e-3, t1: 8}
experiments:
  - name: pd
    controller: {type: pd_gravity, kp: {cart: 40}, kd: {cart: 20}}
    plant_forces: [{type: effort, joint: cart, value: 2}]
  - name: pid
    controller: {type: pid_gravity, kp: {cart: 40}, ki: {cart: 30}, kd: {cart: 20}}
    plant_forces: [{type: effort, joint: cart, value: 2}]
)";
  const auto p = io::parse_problem(text, "slider.yaml");
  io::RunOptions o;
  o.track = true;
  const io::Results r = io::run_problem(*p, o);
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r.runs.size(), 2u);
  const ClosedLoopResult& pd = r.runs[0].result;
  const ClosedLoopResult& pid = r.runs[1].result;
  // PD: at rest −K_p e + F = 0, e = F/K_p = 0.05 (the reference stays at 0: no forces in the plan).
  EXPECT_NEAR(pd.x.back()[0], 2.0 / 40.0, 1e-6);
  EXPECT_TRUE(pd.state_names.empty());
  // PID: e → 0 and the integral settles where K_i ξ = F.
  ASSERT_EQ(pid.state_names, std::vector<std::string>{"xi_cart"});
  ASSERT_EQ(pid.x.back().size(), 3);
  EXPECT_NEAR(pid.x.back()[0], 0.0, 1e-5);
  EXPECT_NEAR(pid.x.back()[2], 2.0 / 30.0, 1e-5);
  // The closed loop m ë + K_d ė + K_p e + K_i ξ = F, ξ̇ = e is linear: compare it with its own
  // RK4 solution on a 10× finer grid (an independent integration of the same ODE).
  Eigen::Vector3d y(0, 0, 0);  // e, ė, ξ
  const double m = 2, kp = 40, kd = 20, ki = 30, F = 2, h = 1e-4;
  auto f = [&](const Eigen::Vector3d& s) {
    return Eigen::Vector3d(s[1], (F - kd * s[1] - kp * s[0] - ki * s[2]) / m, s[0]);
  };
  double worst = 0;
  size_t k = 0;
  for (long i = 0; i <= 80000; ++i) {
    const double t = i * h;
    while (k < pid.t.size() && pid.t[k] <= t + 1e-12) {
      if (std::abs(pid.t[k] - t) < 1e-9) worst = std::max(worst, std::abs(pid.x[k][0] - y[0]));
      ++k;
    }
    const Eigen::Vector3d k1 = f(y), k2 = f(y + 0.5 * h * k1), k3 = f(y + 0.5 * h * k2), k4 = f(y + h * k3);
    y += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  EXPECT_LT(worst, 1e-9) << "the PID closed loop differs from its linear ODE";
}

// ---------------------------------------------------------------------------------------------
// The YAML layer: structure errors with lines, before any number is evaluated.
// Unnamed force elements of one type (issue 24): each keeps the bare column names when it is the
// only one recording them (the paper's psi_dr), and is suffixed with its joint when several
// would record the same name; a named one is suffixed with its name; names that still coincide
// are an error located at the second element.
// SpecReader::quantity: one evaluation gives the value, the text as written and where; an
// expression's text travels with the number into the built object (its symbolic form), a
// literal's does not.
TEST(Spec, QuantityKeepsTextAndLocation) {
  SpecReader c("q.yaml", {{"m2", 3.0}});
  const Quantity e = c.quantity(SpecValue::scalar("m2 * 0.5", {"q.yaml", 7}), "forces[0].stiffness");
  EXPECT_EQ(e.value, 1.5);
  EXPECT_EQ(e.text, "m2 * 0.5");
  EXPECT_EQ(e.where.file, "q.yaml");
  EXPECT_EQ(e.where.line, 7);
  EXPECT_FALSE(e.literal);
  EXPECT_EQ(e.number().text, "m2 * 0.5");
  EXPECT_EQ(symbolic_number(e.number()), "(m2 * 0.5)");
  const Quantity l = c.quantity(SpecValue::scalar("0.3", {"q.yaml", 8}), "x");
  EXPECT_EQ(l.value, 0.3);
  EXPECT_EQ(l.text, "0.3");
  EXPECT_TRUE(l.literal);
  EXPECT_TRUE(l.number().text.empty());
  EXPECT_EQ(symbolic_number(l.number()), symbolic_number(0.3));
  try {
    c.quantity(SpecValue::scalar("m3 + 1", {"q.yaml", 9}), "forces[0].damping");
    ADD_FAILURE() << "expected an error";
  } catch (const Error& err) {
    EXPECT_EQ(std::string(err.what()).rfind("q.yaml:9: forces[0].damping: ", 0), 0u) << err.what();
  }
  // The built object carries the texts: a spring written with k and a literal rest.
  const auto p = io::parse_problem(R"(name: q
parameters: {k: 2}
model:
  dh:
    joints:
      - {name: j1, type: revolute, a: 0.5, mass: 1, com: [-0.25, 0, 0], inertia: [0.01, 0.05, 0.05]}
forces:
  - {type: spring, joint: j1, stiffness: 2*k, rest: 0.25}
initial: {q: {j1: 0.1}}
integrator: {method: rk4, step: 1e-3, t0: 0, t1: 0.01}
)", "q.yaml");
  const auto form = p->forces.elements()[0]->symbolic(p->model);
  ASSERT_TRUE(form);
  EXPECT_TRUE(form->scenario_texts);
  EXPECT_EQ(form->rows[0], "-(2*k)*(q(j1) - " + symbolic_number(0.25) + ")");
}

TEST(Spec, UnnamedForceElementsAreToldApartByTheirJoints) {
  auto drive = [](const std::string& joint, const std::string& name) {
    return "  - {type: flexible_drive, joint: " + joint + ", stiffness: 50, damping: 2" +
           (name.empty() ? "" : ", name: " + name) + ", profile: {raised_cosine: {base: 0, amplitude: 0.1, period: 1}}}\n";
  };
  auto signals = [](const std::string& forces) {
    const auto p = io::parse_problem(arm("forces:\n" + forces), "drives.yaml");
    std::vector<std::string> names;
    for (const auto& e : p->forces.elements())
      for (const auto& s : e->signal_names()) names.push_back(s);
    return names;
  };
  using V = std::vector<std::string>;
  EXPECT_EQ(signals(drive("j1", "")), (V{"psi_dr", "tau_drive"}));
  EXPECT_EQ(signals(drive("j1", "") + drive("j2", "")), (V{"psi_dr_j1", "tau_drive_j1", "psi_dr_j2", "tau_drive_j2"}));
  EXPECT_EQ(signals(drive("j1", "") + drive("j2", "shoulder")), (V{"psi_dr", "tau_drive", "psi_dr_shoulder", "tau_drive_shoulder"}));
  EXPECT_EQ(signals(drive("j1", "a") + drive("j2", "b")), (V{"psi_dr_a", "tau_drive_a", "psi_dr_b", "tau_drive_b"}));
  EXPECT_EQ(signals(drive("j1", "") + "  - {type: damping, joint: j1, coefficient: 0.5}\n" + drive("j2", "")),
            (V{"psi_dr_j1", "tau_drive_j1", "psi_dr_j2", "tau_drive_j2"}));
  // Two unnamed drives on the same joint, or a drive named after the joint of an unnamed one.
  test::expect_error_mentioning([&] { signals(drive("j1", "") + drive("j1", "")); },
                                {"drives.yaml:", "forces[1]", "two force elements record 'psi_dr_j1'"});
  test::expect_error_mentioning([&] { signals(drive("j1", "") + drive("j2", "") + drive("j2", "j1")); },
                                {"forces[2]", "two force elements record 'psi_dr_j1'"});

  // The same for states: two LuGre elements on one joint (before: two columns named z_j2).
  auto lugre = [](const std::string& name) {
    return "  - {type: lugre, joint: j2, mu_s: 0.1, mu_k: 0.2, sigma0: 5.0, stribeck_velocity: 0.175" +
           (name.empty() ? "" : ", name: " + name) + "}\n";
  };
  auto states = [](const std::string& forces) {
    return io::parse_problem(arm("forces:\n" + forces), "lugre.yaml")->forces.state_names();
  };
  EXPECT_EQ(states(lugre("")), (V{"z_j2"}));
  EXPECT_EQ(states(lugre("a")), (V{"z_j2"})) << "a lone named element keeps its column";
  EXPECT_EQ(states(lugre("") + lugre("")), (V{"z_j2_1", "z_j2_2"}));
  EXPECT_EQ(states(lugre("a") + lugre("b")), (V{"z_j2_a", "z_j2_b"}));
  EXPECT_EQ(states(lugre("") + lugre("b")), (V{"z_j2_1", "z_j2_b"}));
  test::expect_error_mentioning([&] { states(lugre("") + lugre("1")); },
                                {"lugre.yaml:", "forces[1]", "two force elements have the state 'z_j2_1'"});
}

TEST(Spec, DuplicateKeysAreRejectedWithBothLines) {
  test::expect_error_mentioning([] { io::parse_scenario(arm("integrator: {t1: 1}\n"), "dup.yaml"); },
                                {"dup.yaml:", "integrator", "given twice", "lines 14 and 15"});
  test::expect_error_mentioning(
      [] { io::parse_scenario(arm("controller: {type: pd_gravity, kp: [1, 1], kp: [2, 2], kd: [1, 1]}\n"), "dup.yaml"); },
      {"controller.kp", "given twice"});
}

TEST(Spec, SecondDocumentComplexKeysAndReservedNamesAreRejected) {
  test::expect_error_mentioning([] { io::parse_scenario(arm("---\nname: other\n"), "two.yaml"); },
                                {"two.yaml:", "second YAML document"});
  test::expect_error_mentioning([] { io::parse_scenario(arm("? [a, b]\n: 1\n"), "complex.yaml"); },
                                {"complex.yaml:", "plain name as a mapping key"});
  for (const char* name : {"pi", "e", "deg"}) {
    std::string text = arm("");
    text.replace(text.find("L2: 0.4}"), 8, std::string("L2: 0.4, ") + name + ": 3}");
    const ScenarioSpec spec = io::parse_scenario(text, "reserved.yaml");  // structure is fine
    test::expect_error_mentioning([&] { build_problem(spec); }, {"reserved.yaml:", std::string("parameters.") + name, "reserved"});
  }
}

TEST(Spec, TheSpecKeepsNumbersAsWrittenAndBuildEvaluatesThem) {
  const ScenarioSpec spec = io::parse_scenario(arm("baumgarte: {alpha: 2*L1, beta: 7}\n"), "arm.yaml");
  EXPECT_EQ(spec.baumgarte.alpha.text, "2*L1");
  EXPECT_EQ(spec.baumgarte.alpha.where.line, 15);
  const auto p = build_problem(spec);
  EXPECT_EQ(p->options.alpha, 1.0);
  EXPECT_EQ(p->options.beta, 7.0);
}

TEST(Spec, SolverAutoIsResolvedBySizeWhenTheProblemIsBuilt) {
  // The 2-DOF arm is below kLagrangeFrom: auto is the projection; explicit choices stay.
  EXPECT_EQ(io::parse_problem(arm("solver: auto\n"), "arm.yaml")->options.solver, automatic_reference_solver(2, 0));
  EXPECT_EQ(io::parse_problem(arm("solver: auto\n"), "arm.yaml")->options.solver, ReferenceSolver::Projection);
  EXPECT_EQ(io::parse_problem(arm("solver: lagrange\n"), "arm.yaml")->options.solver, ReferenceSolver::Lagrange);
  EXPECT_EQ(io::parse_problem(arm(""), "arm.yaml")->options.solver, ReferenceSolver::Projection);  // default: auto
  test::expect_error_mentioning([] { io::parse_problem(arm("solver: fastest\n"), "arm.yaml"); },
                                {"arm.yaml:", "solver", "auto", "fastest"});
}

TEST(Spec, SweepParameterMayNotShadowAParameter) {
  const std::string text = arm(R"(controller: {type: pd_gravity, kp: [1, 1], kd: [1, 1]}
experiments:
  - {name: "r{L1}", sweep: {L1: [1, 2]}}
)");
  test::expect_error_mentioning([&] { io::parse_problem(text, "shadow.yaml"); },
                                {"shadow.yaml:", "experiments[0].sweep.L1", "name of a parameter"});
}

// ---------------------------------------------------------------------------------------------
// Result files: one writer each; JSON stays valid whatever the names.
TEST(Results, SummaryJsonIsValidForHostileNamesAndTablesHaveTheDocumentedColumns) {
  std::string text = arm(R"(constraints:
  - name: tip
    expression: x(E) - (L1 + 0.05*(1 - cos(2*pi*t))/2)
forces: [{type: effort, joint: j2, value: 0.1}]
)");
  text.replace(text.find("name: arm"), 9, "name: \"a\\\"b\\\\c ψ\"");
  const auto p = io::parse_problem(text, "names.yaml");
  EXPECT_EQ(p->name, "a\"b\\c ψ");
  const io::Results r = io::run_problem(*p);
  ASSERT_TRUE(r.ok());
  const fs::path dir = fs::temp_directory_path() / ("refdyn_results_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  io::write_results(dir, *p, r, io::summary_json(*p, r));
  const std::string check = "/usr/bin/python3 -c \"import json,sys; json.load(open(sys.argv[1])); json.load(open(sys.argv[2]))\" '" +
                            (dir / "summary.json").string() + "' '" + (dir / "feasibility.json").string() + "'";
  EXPECT_EQ(std::system(check.c_str()), 0) << "summary.json or feasibility.json is not valid JSON";
  std::ifstream f(dir / "plan.csv");
  std::string header;
  std::getline(f, header);
  EXPECT_EQ(header,
            "t,q_j1,q_j2,qd_j1,qd_j2,qdd_j1,qdd_j2,E_x,E_y,E_z,O_x,O_y,O_z,phi_tip,phid_tip,Qc_j1,Qc_j2,required_j1,"
            "required_j2,lambda_tip");
  fs::remove_all(dir);
  EXPECT_EQ(json_quote("a\"b\\c\n\x01\xff"), "\"a\\\"b\\\\c\\n\\u0001\\ufffd\"");
  EXPECT_TRUE(valid_utf8("ψ₁"));
  EXPECT_FALSE(valid_utf8("\xc3\x28"));
}

// A programmed motion with a kink: RK4 stages land exactly on the switch (t = 1/4, step 2^-10),
// where min's derivative used to be NaN; the plan runs through and the motion stops there.
TEST(Pipeline, ProgrammedMotionThroughAKinkRunsThrough) {
  const std::string text = arm(R"(constraints:
  - name: tip
    expression: x(E) - (L1 + 0.1*(1 - cos(pi*min(t, 0.25)/0.25))/2)
partition: {independent: [j2]}
)");
  std::string t2 = text;
  t2.replace(t2.find("step: 1e-3"), 10, "step: 0.0009765625");
  t2.replace(t2.find("t1: 0.2"), 7, "t1: 0.5");
  const auto p = io::parse_problem(t2, "kink.yaml");
  const io::Results r = io::run_problem(*p);
  ASSERT_TRUE(r.plan.summary.ok()) << r.plan.summary.message;
  EXPECT_TRUE(r.feasibility.feasible());
  bool passed_switch = false;
  for (size_t k = 0; k < r.plan.size(); ++k) {
    ASSERT_TRUE(r.plan.qdd[k].allFinite()) << "t = " << r.plan.t[k];
    passed_switch = passed_switch || r.plan.t[k] == 0.25;
    // After the switch the tip rests at x(E) = L1 + 0.1. The programmed acceleration jumps there
    // (by (π/0.25)²·0.05 = 7.9 m/s²), which costs RK4 one first-order step (~h·Δa·h ~ 1e-5 m);
    // Baumgarte stabilisation then pulls the residual back.
    if (r.plan.t[k] > 0.3) {
      EXPECT_NEAR(r.plan.point_positions[k][0], 0.6, 1e-5) << "t = " << r.plan.t[k];
    }
  }
  EXPECT_TRUE(passed_switch) << "no sample at the switch";
  EXPECT_NEAR(r.plan.point_positions.back()[0], 0.6, 1e-6) << "the residual must decay";
}
