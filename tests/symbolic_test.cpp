// generate_symbolic (src/symbolic/): closed-form mass matrix of a 2R arm read back from the JSON,
// parameters kept symbolic, LaTeX structure (and a pdflatex run when it is installed), the
// C writer's common-subexpression elimination, errors, and the `refdyn generate` command.
// The generated C against the numeric engine: symbolic_c_test.cpp.
#include "refdyn/expression/expression.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/symbolic/symbolic.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <map>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <sys/wait.h>
#include <unistd.h>

namespace refdyn {
namespace {

namespace fs = std::filesystem;

std::string example(const std::string& name) {
  return std::string(REFDYN_SOURCE_DIR) + "/examples/" + name + "/" + name + ".yaml";
}

std::string read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// The JSON array of strings after "key": [...] (flattened, for M), as written.
std::vector<std::string> json_raw_strings_of(const std::string& json, const std::string& key) {
  std::vector<std::string> out;
  auto k = json.find("\"" + key + "\": [");
  if (k == std::string::npos) return out;
  int depth = 0;
  std::size_t i = json.find('[', k);
  for (; i < json.size(); ++i) {
    if (json[i] == '[') ++depth;
    if (json[i] == ']' && --depth == 0) break;
    if (json[i] == '"') {
      const auto e = json.find('"', i + 1);
      out.push_back(json.substr(i + 1, e - i - 1));
      i = e;
    }
  }
  return out;
}

/// A formula of the JSON with its auxiliaries aux(k) written out (each names only earlier ones).
std::string with_auxiliaries(std::string text, const std::string& json) {
  const std::vector<std::string> aux = json_raw_strings_of(json, "auxiliaries");
  for (std::size_t k = aux.size(); k >= 1; --k) {
    const std::string name = "aux(" + std::to_string(k) + ")";
    for (std::size_t at = text.find(name); at != std::string::npos; at = text.find(name, at))
      text.replace(at, name.size(), "(" + aux[k - 1] + ")");
  }
  return text;
}

/// The JSON string value of "key" (first occurrence after `from`), unescaped (no escapes
/// expected), auxiliaries written out.
std::string json_string_after(const std::string& json, const std::string& key, std::size_t from = 0) {
  const auto k = json.find("\"" + key + "\": ", from);
  if (k == std::string::npos) return "";
  const auto a = json.find('"', k + key.size() + 4);
  const auto b = json.find('"', a + 1);
  return with_auxiliaries(json.substr(a + 1, b - a - 1), json);
}

/// The JSON array of strings after "key": [...] (flattened, for M), auxiliaries written out.
std::vector<std::string> json_strings_of(const std::string& json, const std::string& key) {
  std::vector<std::string> out = json_raw_strings_of(json, key);
  for (std::string& s : out) s = with_auxiliaries(s, json);
  return out;
}

/// The "parameters": {name: value, ...} object.
std::map<std::string, double> json_parameters(const std::string& json) {
  std::map<std::string, double> out;
  const auto a = json.find("\"parameters\": {");
  const auto b = json.find('}', a);
  std::string body = json.substr(a + 15, b - a - 15);
  std::size_t i = 0;
  while ((i = body.find('"', i)) != std::string::npos) {
    const auto e = body.find('"', i + 1);
    const std::string name = body.substr(i + 1, e - i - 1);
    const auto colon = body.find(':', e);
    out[name] = std::strtod(body.c_str() + colon + 1, nullptr);
    i = body.find(',', colon);
    if (i == std::string::npos) break;
  }
  return out;
}

TEST(GenerateSymbolic, PlanarArmMassMatrixIsTheClosedForm) {
  const auto problem = io::load_problem(example("planar_2r_circle"));
  const SymbolicReferenceDynamics g = generate_symbolic(*problem);
  const std::string json = g.json();
  const std::vector<std::string> M = json_strings_of(json, "M");
  ASSERT_EQ(M.size(), 4u) << json;
  // the scenario names the lengths and masses: they stay symbols of the formulas
  const std::map<std::string, double> params = json_parameters(json);
  for (const char* name : {"L1", "L2", "m1", "m2"}) EXPECT_EQ(params.count(name), 1u) << name << " in " << json;
  EXPECT_NE(M[0].find("m2"), std::string::npos) << M[0];
  EXPECT_NE(M[0].find("L1"), std::string::npos) << M[0];
  // uniform bars along x, com at L/2, I_zz = m L²/12 about the centre of mass
  const double L1 = 0.5, L2 = 0.4, m1 = 2.0, m2 = 1.5;
  const double I1 = m1 * L1 * L1 / 12, I2 = m2 * L2 * L2 / 12, c1 = L1 / 2, c2 = L2 / 2;
  for (double q2 : {-2.0, -0.3, 0.0, 0.7, 2.5}) {
    const double q1 = 0.4 * q2 + 0.1;
    const double x[2] = {q1, q2};
    const double M11 = I1 + m1 * c1 * c1 + I2 + m2 * (L1 * L1 + c2 * c2 + 2 * L1 * c2 * std::cos(q2));
    const double M12 = I2 + m2 * (c2 * c2 + L1 * c2 * std::cos(q2));
    const double M22 = I2 + m2 * c2 * c2;
    const std::vector<double> expected{M11, M12, M12, M22};
    for (int k = 0; k < 4; ++k) {
      const Expression e(M[k], {"q(q1)", "q(q2)"}, params, 0);
      EXPECT_NEAR(e.value(x), expected[k], 1e-14) << "M entry " << k << ": " << M[k];
    }
    // gravity (along −y): g_2 = m2 g c2 cos(q1 + q2)
    const std::vector<std::string> gv = json_strings_of(json, "g");
    ASSERT_EQ(gv.size(), 2u);
    const Expression g2(gv[1], {"q(q1)", "q(q2)"}, params, 0);
    EXPECT_NEAR(g2.value(x), m2 * 9.81 * c2 * std::cos(q1 + q2), 1e-13);
  }
}

TEST(GenerateSymbolic, JsonFormulasEvaluateToTheEngine) {
  // The paper example's Q (flexible drive with a clamped cycloid, LuGre with abs and states) and
  // constraint rows, printed as expression-language texts, parsed back and evaluated.
  const auto problem = io::load_problem(example("paper"));
  const std::string json = generate_symbolic(*problem).json();
  const std::map<std::string, double> params = json_parameters(json);
  const Model& model = problem->model;
  const int n = model.nq, nz = problem->forces.num_states(), m = problem->constraints.rows();
  std::vector<std::string> vars;
  for (int i = 0; i < n; ++i) vars.push_back("q(" + model.joint_name[i] + ")");
  for (int i = 0; i < n; ++i) vars.push_back("qd(" + model.joint_name[i] + ")");
  for (int k = 0; k < nz; ++k) vars.push_back("state(" + std::to_string(k) + ")");
  vars.push_back("t");
  const std::vector<std::string> Q = json_strings_of(json, "Q");
  ASSERT_EQ(static_cast<int>(Q.size()), n);
  Data data(model);
  ConstraintEval ev(model, problem->constraints);
  for (double t : {0.0, 1.3, 2.5, 5.0, 6.0}) {  // before, during, at the end of and after the drive's rise
    Eigen::VectorXd q = problem->q0, qd(n), z(nz), Qe(n), zd(nz);
    for (int i = 0; i < n; ++i) qd[i] = 0.3 * (i + 1) - 0.5;
    for (int k = 0; k < nz; ++k) z[k] = 1e-3 * (k - 1);
    std::vector<double> x;
    for (int i = 0; i < n; ++i) x.push_back(q[i]);
    for (int i = 0; i < n; ++i) x.push_back(qd[i]);
    for (int k = 0; k < nz; ++k) x.push_back(z[k]);
    x.push_back(t);
    problem->forces.evaluate(t, q, qd, z.data(), Qe, zd.data());
    for (int i = 0; i < n; ++i)
      EXPECT_NEAR(Expression(Q[i], vars, params, 0).value(x.data()), Qe[i], 1e-12 * std::max(1.0, std::abs(Qe[i])))
          << "Q[" << i << "] at t = " << t << ": " << Q[i];
    evaluate_constraints(model, data, problem->constraints, ev, t, q, qd);
    std::size_t at = json.find("\"constraints\"");
    for (int r = 0; r < m; ++r) {
      at = json.find("\"phi\"", at + 1);
      const std::string phi = json_string_after(json, "phi", at), gamma = json_string_after(json, "gamma", at);
      EXPECT_NEAR(Expression(phi, vars, params, 0).value(x.data()), ev.phi[r], 1e-13) << phi;
      EXPECT_NEAR(Expression(gamma, vars, params, 0).value(x.data()), ev.gamma[r], 1e-12 * std::max(1.0, std::abs(ev.gamma[r])))
          << gamma;
    }
  }
}

TEST(GenerateSymbolic, ScenarioParametersStaySymbolic) {
  const auto problem = io::load_problem(example("planar_2r_circle"));
  const SymbolicReferenceDynamics g = generate_symbolic(*problem);
  EXPECT_EQ(g.summary().nq, 2);
  EXPECT_EQ(g.summary().constraints, 2);
  const std::string json = g.json();
  // the circle: (x(E) - cx)^2 + (y(E) - cy)^2 - R^2 keeps cx, cy, R; the speed keeps v0
  const std::string phi = json_string_after(json, "phi");
  for (const char* name : {"cx", "cy", "R"}) EXPECT_NE(phi.find(name), std::string::npos) << phi;
  for (const char* name : {"\"cx\": 0.59999999999999998", "\"R\": 0.14999999999999999", "\"v0\": "})
    EXPECT_NE(json.find(name), std::string::npos) << name;
  const std::string h = g.c_header();
  for (const char* field : {"double cx;", "double cy;", "double R;", "double v0;", "double rd_alpha;"})
    EXPECT_NE(h.find(field), std::string::npos) << field;
  const std::string c = g.c_source();
  EXPECT_NE(c.find("p->R"), std::string::npos);
  EXPECT_NE(c.find("p->R = 0.14999999999999999;"), std::string::npos);
}

TEST(GenerateSymbolic, ReadyMadeKindsKeepTheScenarioNames) {
  // paper.yaml: point_on_ellipse {a: a, b: b}, point_coordinate with raised_cosine {base: z0,
  // amplitude: dz, period: Tz}, DH d: h1, flexible drive rise 2*pi: the names stay in the formulas.
  const auto problem = io::load_problem(example("paper"));
  const std::string json = generate_symbolic(*problem).json();
  const std::map<std::string, double> params = json_parameters(json);
  for (const char* name : {"a", "b", "z0", "dz", "Tz", "h1"}) EXPECT_EQ(params.count(name), 1u) << name << ": " << json;
  EXPECT_EQ(params.at("a"), 0.35355339059327373);
  const std::size_t rows = json.find("\"constraints\"");
  const std::string ellipse = json_string_after(json, "phi", rows);
  EXPECT_NE(ellipse.find("/a^2"), std::string::npos) << ellipse;
  EXPECT_NE(ellipse.find("/b^2"), std::string::npos) << ellipse;
  const std::string height = json_string_after(json, "phi", json.find("\"phi\"", rows) + 1);
  for (const char* name : {"h1", "dz", "Tz", "z0"}) EXPECT_NE(height.find(name), std::string::npos) << height;
  // numbers written as literals stay numbers (no parameter is invented for them)
  EXPECT_EQ(params.count("deg"), 0u);
  const std::string h = generate_symbolic(*problem).c_header();
  EXPECT_NE(h.find("double a;"), std::string::npos);
  EXPECT_NE(h.find("double Tz;"), std::string::npos);
}

// The names come from the numbers themselves (SpecReader::quantity → Number), not from matching
// values back to texts: two parameters with the same value keep their own names, and a literal
// equal to a parameter's value stays a number (value matching named both `k`, or neither).
TEST(GenerateSymbolic, EqualValuesKeepTheirOwnNames) {
  const std::string yaml = R"(name: same_values
parameters: {k: 0.5, r: 0.5, L1: 0.5}
model:
  gravity: [0, 0, 0]
  dh:
    joints:
      - {name: j1, type: revolute, a: L1, mass: 1, com: [-0.25, 0, 0], inertia: [0.01, 0.05, 0.05]}
      - {name: j2, type: revolute, a: 0.4, mass: 1, com: [-0.2, 0, 0], inertia: [0.005, 0.02, 0.02]}
  points:
    E: {link: j2, position: [0, 0, 0]}
constraints:
  - {name: tip_x, kind: point_coordinate, point: E, axis: x, function: 0.7}
partition: {independent: [j2]}
forces:
  - {type: spring, joint: j1, stiffness: k, rest: r}
  - {type: spring, joint: j2, stiffness: k, rest: 0.5}
initial: {q: {j1: 0.3, j2: 1.2}, consistency: project}
integrator: {method: rk4, step: 1e-3, t0: 0, t1: 0.01}
)";
  const auto problem = io::parse_problem(yaml, "same_values.yaml");
  const std::string json = generate_symbolic(*problem).json();
  const std::map<std::string, double> params = json_parameters(json);
  EXPECT_EQ(params.count("k"), 1u) << json;
  EXPECT_EQ(params.count("r"), 1u) << json;
  const std::size_t q = json.find("\"Q\"");
  ASSERT_NE(q, std::string::npos);
  const std::string Q = json.substr(q, json.find(']', q) - q);
  const std::size_t second = Q.find("\", \"");
  ASSERT_NE(second, std::string::npos) << Q;
  const std::string q1 = Q.substr(0, second), q2 = Q.substr(second);
  const std::regex k(R"(\bk\b)"), r(R"(\br\b)"), half(R"(0\.5\b)");
  // j1: −k (q1 − r): both names, no 0.5
  EXPECT_TRUE(std::regex_search(q1, k)) << q1;
  EXPECT_TRUE(std::regex_search(q1, r)) << q1;
  EXPECT_FALSE(std::regex_search(q1, half)) << q1;
  // j2: −k (q2 − 0.5): the literal stays a number, r (same value) does not appear
  EXPECT_TRUE(std::regex_search(q2, k)) << q2;
  EXPECT_FALSE(std::regex_search(q2, r)) << q2;
  EXPECT_TRUE(std::regex_search(q2, half)) << q2;
}

TEST(GenerateSymbolic, CommonSubexpressionEliminationShrinksTheCode) {
  const auto problem = io::load_problem(example("paper"));
  SymbolicOptions with, without;
  without.cse = false;
  const SymbolicReferenceDynamics a = generate_symbolic(*problem, with), b = generate_symbolic(*problem, without);
  a.c_source();
  b.c_source();
  EXPECT_GT(a.summary().c_temporaries, 0);
  EXPECT_EQ(b.summary().c_temporaries, 0);
  EXPECT_LT(a.summary().c_operations, b.summary().c_operations);
  std::printf("paper model: %ld operations with CSE (%ld temporaries), %ld without\n", a.summary().c_operations,
              a.summary().c_temporaries, b.summary().c_operations);
}

/// The first sine or cosine of a number in text ("sin(1.57079632679)", "cos(-0.3)"), or "".
std::string sine_of_a_number(const std::string& text) {
  for (const char* f : {"sin(", "cos("})
    for (std::size_t at = text.find(f); at != std::string::npos; at = text.find(f, at + 4)) {
      std::size_t k = at + 4;
      if (k < text.size() && text[k] == '-') ++k;
      const std::size_t digits = k;
      while (k < text.size() && (std::isdigit(static_cast<unsigned char>(text[k])) || text[k] == '.' || text[k] == 'e' ||
                                 ((text[k] == '-' || text[k] == '+') && text[k - 1] == 'e')))
        ++k;
      if (k > digits && k < text.size() && text[k] == ')') return text.substr(at, k + 1 - at);
    }
  return "";
}

// Rounded π in joint origins (the test arms' URDFs: 1.57079632679, 3.14159265359) leaves rotation
// entries of 1e-12 where 0 was meant, and a links model's rpy (every_kind.yaml: 0.3, 0.2) gives
// dense ones: numeric model constants are numbers of the generated code, never sines of numbers
// kept as symbols, and the generation stays small (issue 33, item 2: ≤ 10 MB per format; before,
// arm6 wrote a 23 MB JSON and a 6-joint arm with rounded π 408 MB).
TEST(GenerateSymbolic, RoundedPiArmsStaySmall) {
  const std::string urdf = std::string(REFDYN_SOURCE_DIR) + "/tests/data/urdf/";
  struct Bound {
    std::string file;
    std::size_t c, json, latex;
  };
  for (const Bound& b : {Bound{urdf + "arm6.yaml", 1000000, 4000000, 4000000},
                         Bound{urdf + "arm7_hand.yaml", 1000000, 4000000, 4000000},
                         Bound{std::string(REFDYN_SOURCE_DIR) + "/tests/data/symbolic/every_kind.yaml", 1000000, 1000000,
                               1000000}}) {
    SCOPED_TRACE(b.file);
    const auto problem = io::load_problem(b.file);
    const SymbolicReferenceDynamics g = generate_symbolic(*problem);
    const std::string c = g.c_source(), json = g.json(), tex = g.latex();
    std::printf("%s: generated in %.2f s, C %zu bytes, JSON %zu, LaTeX %zu\n", fs::path(b.file).filename().c_str(),
                g.summary().seconds, c.size(), json.size(), tex.size());
    EXPECT_LT(c.size(), b.c);
    EXPECT_LT(json.size(), b.json);
    EXPECT_LT(tex.size(), b.latex);
    EXPECT_EQ(sine_of_a_number(c), "");
    EXPECT_EQ(sine_of_a_number(json), "");
  }
}

TEST(GenerateSymbolic, LatexDocumentIsWellFormed) {
  const auto problem = io::load_problem(example("paper"));
  const std::string tex = generate_symbolic(*problem).latex();
  EXPECT_EQ(tex.find("\\documentclass"), tex.find('\n') + 1);
  EXPECT_NE(tex.find("\\begin{document}"), std::string::npos);
  EXPECT_NE(tex.rfind("\\end{document}\n"), std::string::npos);
  EXPECT_EQ(tex.rfind("\\end{document}\n") + 15, tex.size());
  int depth = 0, min_depth = 0;
  for (std::size_t i = 0; i < tex.size(); ++i) {
    if (tex[i] == '\\' && i + 1 < tex.size() && (tex[i + 1] == '{' || tex[i + 1] == '}')) {
      ++i;
      continue;
    }
    if (tex[i] == '{') ++depth;
    if (tex[i] == '}') min_depth = std::min(min_depth, --depth);
  }
  EXPECT_EQ(depth, 0);
  EXPECT_EQ(min_depth, 0);
  auto count = [&](const std::string& s) {
    std::size_t n = 0;
    for (auto p = tex.find(s); p != std::string::npos; p = tex.find(s, p + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count("\\begin{align*}"), count("\\end{align*}"));
  EXPECT_EQ(count("\\left"), count("\\right"));
  for (const char* entry : {"M_{11} &=", "M_{33} &=", "c_{1} &=", "g_{2} &=", "Q_{1} &=", "\\Phi_{1} &=",
                            "\\gamma_{2} &=", "\\dot z_{1} &=", "q_{ic} = (q_{1})"})
    EXPECT_NE(tex.find(entry), std::string::npos) << entry;
  // the prismatic coordinate's mass entry is the total sliding mass
  EXPECT_NE(tex.find("M_{33} &= 3 \\\\"), std::string::npos);

  // Compile it when pdflatex is installed (texlive-latex-base; optional).
  if (std::system("command -v pdflatex >/dev/null 2>&1") != 0) GTEST_SKIP() << "pdflatex not installed";
  const fs::path dir = fs::temp_directory_path() / ("refdyn_tex_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "equations.tex") << tex;
  const std::string cmd = "cd '" + dir.string() +
                          "' && pdflatex -interaction=nonstopmode -halt-on-error equations.tex >log.txt 2>&1";
  const int status = std::system(cmd.c_str());
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << read(dir / "log.txt");
  EXPECT_TRUE(fs::exists(dir / "equations.pdf"));
  fs::remove_all(dir);
}

TEST(GenerateSymbolic, RejectsWhatItCannotGenerate) {
  std::string yaml = read(example("planar_2r_circle"));
  yaml += "\npaper_literal_forces: true\n";
  const auto problem = io::parse_problem(yaml, example("planar_2r_circle"));
  test::expect_error_mentioning([&] { generate_symbolic(*problem); }, {"paper-literal"});
  // a jerk row (p = 3) is generated (state [q, q̇, q̈]; the C compared with JerkDynamics in
  // symbolic_c_test): a prismatic joint and a row nonlinear in the velocities
  const char* jerk = R"(
name: particle_jerk
model:
  links:
    - {name: arm, joint: th, parent: base, type: revolute, axis: [0, 0, 1], mass: 0, inertia: [0, 0, 0]}
    - {name: bead, joint: r, parent: arm, type: prismatic, axis: [1, 0, 0], mass: 1.7, inertia: [0, 0, 0]}
  points:
    P: {link: bead, position: [0, 0, 0]}
constraints:
  - name: tangential_jerk
    order: jerk
    expression: (vx(P)*jx(P) + vy(P)*jy(P))/sqrt(vx(P)^2 + vy(P)^2) - 0.9*sin(2*t)
initial:
  q: {th: 0, r: 1}
  qd: {th: 0.8, r: 0.3}
integrator: {method: rk4, step: 0.01, t0: 0, t1: 3}
)";
  const auto jp = io::parse_problem(jerk, "jerk.yaml");
  const SymbolicReferenceDynamics jg = generate_symbolic(*jp);
  EXPECT_NE(jg.c_header().find("#define RD_PARTICLE_JERK_NX 6\n"), std::string::npos) << jg.c_header();
  EXPECT_NE(jg.c_header().find("rd_particle_jerk_jerk("), std::string::npos);
  EXPECT_NE(jg.json().find("\"order\": \"jerk\""), std::string::npos);
  EXPECT_NE(jg.latex().find("Jerk level"), std::string::npos);
  const auto ok = io::load_problem(example("planar_2r_circle"));
  SymbolicOptions o;
  o.prefix = "9bad prefix";
  test::expect_error_mentioning([&] { generate_symbolic(*ok, o); }, {"prefix", "not a C identifier"});
}

int run(const std::string& args) {
  const std::string cmd = std::string("'") + REFDYN_CLI + "' " + args + " >/dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

TEST(GenerateCommand, WritesTheRequestedFormatsAndNothingOnError) {
  const fs::path dir = fs::temp_directory_path() / ("refdyn_generate_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  EXPECT_EQ(run("generate '" + example("four_bar") + "' -o '" + dir.string() + "' -q"), 0);
  for (const char* f : {"reference_dynamics.c", "reference_dynamics.h", "equations.tex", "reference_dynamics.json"})
    EXPECT_TRUE(fs::exists(dir / f)) << f;
  fs::remove_all(dir);
  EXPECT_EQ(run("generate '" + example("four_bar") + "' -o '" + dir.string() + "' -q --format json,latex"), 0);
  EXPECT_TRUE(fs::exists(dir / "reference_dynamics.json"));
  EXPECT_TRUE(fs::exists(dir / "equations.tex"));
  EXPECT_FALSE(fs::exists(dir / "reference_dynamics.c"));
  fs::remove_all(dir);
  // bad input: exit 2, nothing written
  EXPECT_EQ(run("generate '" + example("four_bar") + "' -o '" + dir.string() + "' --format c,pdf"), 2);
  EXPECT_EQ(run("generate '" + example("four_bar") + "' -o '" + dir.string() + "' --prefix 'a-b'"), 2);
  EXPECT_EQ(run("generate /nonexistent.yaml -o '" + dir.string() + "'"), 2);
  EXPECT_FALSE(fs::exists(dir));
}

std::string file_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream o;
  o << in.rdbuf();
  return o.str();
}

// `refdyn generate` in separate processes (address-space randomization on: GiNaC's hash order
// moves from run to run) writes byte-identical files: the writers are canonical (tape.hpp).
TEST(GenerateCommand, WritesTheSameTextInEveryRun) {
  {
    std::ifstream aslr("/proc/sys/kernel/randomize_va_space");
    int mode = -1;
    if (aslr >> mode && mode == 0) std::printf("note: address-space randomization is off on this machine\n");
  }
  const fs::path base = fs::temp_directory_path() / ("refdyn_same_text_" + std::to_string(::getpid()));
  const std::string data = std::string(REFDYN_SOURCE_DIR) + "/tests/data/symbolic/";
  const std::string urdf = std::string(REFDYN_SOURCE_DIR) + "/tests/data/urdf/";
  // two processes each (address-space randomization, where on, gives GiNaC other hashes in each)
  for (const std::string& file : {example("paper"), example("urdf_arm_line"), example("unicycle"),
                                  data + "every_kind.yaml", data + "arm_jerk.yaml", urdf + "arm7_hand.yaml"}) {
    SCOPED_TRACE(file);
    std::vector<fs::path> dirs;
    for (int run_index = 0; run_index < 2; ++run_index) {
      dirs.push_back(base / std::to_string(run_index));
      ASSERT_EQ(run("generate '" + file + "' -o '" + dirs.back().string() + "' -q"), 0);
    }
    for (const char* f : {"reference_dynamics.c", "reference_dynamics.h", "equations.tex", "reference_dynamics.json"}) {
      const std::string first = file_text(dirs[0] / f);
      ASSERT_FALSE(first.empty()) << f;
      for (size_t k = 1; k < dirs.size(); ++k) EXPECT_TRUE(file_text(dirs[k] / f) == first) << f << " differs in run " << k;
    }
    fs::remove_all(base);
  }
}

}  // namespace
}  // namespace refdyn
