// The canonical graph the generated code is written from (src/symbolic/tape.hpp, private to the
// generator): expressions that GiNaC may build in different forms from run to run — the order of
// its operands follows address-seeded hashes, and some simplifications follow that order — are
// one node. The forms are built here with hold(), which keeps GiNaC from evaluating them.
// The whole-program check (refdyn generate twice, byte-identical files): symbolic_test.cpp.
#include "../src/symbolic/tape.hpp"
#include "refdyn/multibody/generic_dynamics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>

namespace refdyn::symbolic_detail {
namespace {

using GiNaC::dynallocate;
using GiNaC::numeric;
using GiNaC::realsymbol;

ex held_mul(const ex& a, const ex& b) { return dynallocate<GiNaC::mul>(a, b).hold(); }
ex held_pow(const ex& b, const ex& p) { return dynallocate<GiNaC::power>(b, p).hold(); }

TEST(CanonicalGraph, OneNodeForTheFormsGinacMayChoose) {
  const realsymbol x("x"), y("y"), a("a"), b("b");
  Tape tape;
  TapeScope scope(tape);
  FromGinac conv(tape, [](const GiNaC::symbol& s) { return s.get_name(); });
  // a sign pulled out of a sum or not: x − y and −(y − x)
  const ex d1 = x - y, d2 = held_mul(y - x, -1);
  ASSERT_TRUE(GiNaC::is_a<GiNaC::mul>(d2));
  EXPECT_EQ(conv(d1), conv(d2));
  // the content of a sum taken out of a power or not (power::eval does it when the first term's
  // coefficient allows it, first in GiNaC's order): (a/2 + b)² and ¼ (a + 2b)²
  const ex s1 = held_pow(a / 2 + b, 2), s2 = held_mul(numeric(1, 4), held_pow(a + 2 * b, 2));
  ASSERT_TRUE(GiNaC::is_a<GiNaC::mul>(s2));
  EXPECT_EQ(conv(s1), conv(s2));
  // the same with a sign: (−a/2 − b)³ and −⅛ (a + 2b)³
  EXPECT_EQ(conv(held_pow(-a / 2 - b, 3)), conv(held_mul(numeric(-1, 8), held_pow(a + 2 * b, 3))));
  // a sum's content taken out of a product or not (GiNaC normalizes it following its order):
  // one node, the sum normalized by its first non-numeric term in key order
  const ex p1 = held_mul(2 * x + 2 * y, a), p2 = 2 * ((x + y) * a);
  ASSERT_FALSE(p1.is_equal(p2));
  EXPECT_EQ(conv(p1), conv(p2));
  EXPECT_EQ(conv(-p1), tape.neg(conv(p2)));
  // different expressions stay different
  EXPECT_NE(conv(x - y), conv(x + y));
  EXPECT_NE(conv(held_pow(a + b, 2)), conv(held_pow(a - b, 2)));
  // the C text: the sum with its own coefficients
  long temporaries = 0, operations = 0;
  EXPECT_EQ(emit(tape, {{"out", conv(3 * x + 6 * y + 3)}}, true, "", temporaries, operations),
            "out = 3.0*x + 6.0*y + 3.0;\n");
}

TEST(CanonicalGraph, NumbersAreExact) {
  // 0.1 enters as the rational value of the double 0.1: sums of numbers do not depend on order
  const ex v = number(0.1);
  ASSERT_TRUE(GiNaC::ex_to<numeric>(v).is_rational());
  EXPECT_EQ(GiNaC::ex_to<numeric>(v).to_double(), 0.1);
  EXPECT_TRUE((number(0.1) + number(0.2) + number(0.3)).is_equal(number(0.3) + number(0.1) + number(0.2)));
  EXPECT_TRUE(GiNaC::ex_to<numeric>(exact(GiNaC::numeric("0.25"))).is_equal(numeric(1, 4)));
}


/// The value of every node of a Tape at the given leaf values (a test-side interpreter: nodes
/// come after their operands).
std::vector<double> evaluate(const Tape& tape, const std::map<std::string, double>& leaves) {
  std::vector<double> v(tape.size());
  for (std::size_t id = 0; id < tape.size(); ++id) {
    const Tape::Node& n = tape.node(static_cast<int>(id));
    auto a = [&](std::size_t k) { return v[static_cast<std::size_t>(n.args[k])]; };
    switch (n.op) {
      case Tape::Op::Const: v[id] = n.value; break;
      case Tape::Op::Leaf: v[id] = leaves.at(n.text); break;
      case Tape::Op::Add: v[id] = a(0) + a(1); break;
      case Tape::Op::Sub: v[id] = a(0) - a(1); break;
      case Tape::Op::Mul: v[id] = a(0) * a(1); break;
      case Tape::Op::Div: v[id] = a(0) / a(1); break;
      case Tape::Op::Neg: v[id] = -a(0); break;
      case Tape::Op::Pow: v[id] = std::pow(a(0), n.value); break;
      case Tape::Op::Cond: v[id] = (n.value == 1 ? a(0) < a(1) : a(0) <= a(1)) ? a(2) : a(3); break;
      case Tape::Op::Call:
        if (n.text == "sin") v[id] = std::sin(a(0));
        else if (n.text == "cos") v[id] = std::cos(a(0));
        else if (n.text == "sqrt") v[id] = std::sqrt(a(0));
        else ADD_FAILURE() << "unexpected call " << n.text;
        break;
    }
  }
  return v;
}

// Gathering constants, (x + c1) + c2 → x + (c1 + c2), makes the node c1 + c2, which grows the
// Tape's node vector while the sum x + c1 is still read: each step here makes a new constant, so
// the vector grows at that point many times (a read through a reference into the old vector was
// a use after free: `refdyn generate` crashed on a 7-DOF URDF arm; ASan, scripts/test-sanitizers.sh,
// reports it at once). The result must be x + (c1 + c2) every time.
TEST(Tape, GatheringConstantsWhileTheTapeGrows) {
  Tape tape;
  const int x = tape.leaf("x");
  for (int k = 0; k < 5000; ++k) {
    const double c1 = 0.5 + k, c2 = 0.25;
    const int s = tape.add(x, tape.constant(c1));
    const int r = tape.add(s, tape.constant(c2));
    const Tape::Node& n = tape.node(r);
    ASSERT_EQ(n.op, Tape::Op::Add) << k;
    ASSERT_EQ(n.args.size(), 2u);
    const int other = n.args[0] == x ? n.args[1] : n.args[0];
    ASSERT_TRUE(n.args[0] == x || n.args[1] == x) << k;
    ASSERT_TRUE(tape.is_const(other, c1 + c2)) << k;
  }
}

// The composite-rigid-body M and Newton–Euler c + g recorded on the Tape (as `refdyn generate`
// does for its C), evaluated, against the engine's spatial-algebra kernels: random chains and
// trees of 1–10 joints, with URDF-style rounded π in the DH angles (3.14159265359,
// 1.57079632679: rotations with 1e-12 residues) and fixed links. Every node of the CRBA grows the
// Tape (new constants of the folded model), so every place that gathers constants there runs.
TEST(Tape, RecordedDynamicsEqualTheEngineOnRandomChains) {
  std::mt19937 rng(33);
  double worst = 0;
  for (int dof = 1; dof <= 10; ++dof) {
    for (int variant = 0; variant < 3; ++variant) {
      test::RandomChainOptions o;
      o.dof = dof;
      o.tree = variant == 1;
      o.with_fixed_joints = variant >= 1;
      o.modified_dh = variant == 2;
      ModelDescription d = test::random_chain(rng, o);
      if (variant != 1)
        for (LinkSpec& l : d.links)
          if (l.type != JointType::Fixed) {  // URDF-style rounded angles in the placements
            const double r = std::uniform_real_distribution<double>(0, 1)(rng);
            const double angle = r < 0.3 ? 3.14159265359 : r < 0.6 ? 1.57079632679 : r < 0.8 ? -1.57079632679 : 0.0;
            l.placement.R = l.placement.R * Eigen::AngleAxisd(angle, Vec3::UnitX()).toRotationMatrix();
          }
      const Model model = build_model(d);
      const int n = model.nv;
      Tape tape;
      TapeScope scope(tape);
      const multibody::Bodies<TS> B = multibody::bodies_from_model<TS>(model);
      std::vector<TS> q(n), qd(n);
      std::map<std::string, double> leaves;
      const Eigen::VectorXd qv = test::random_vector(rng, n, 2.0), qdv = test::random_vector(rng, n, 2.0);
      for (int i = 0; i < n; ++i) {
        q[i] = TS(tape.leaf("q" + std::to_string(i)));
        qd[i] = TS(tape.leaf("qd" + std::to_string(i)));
        leaves["q" + std::to_string(i)] = qv[i];
        leaves["qd" + std::to_string(i)] = qdv[i];
      }
      const multibody::Poses<TS> P = multibody::forward_poses(B, q);
      const std::vector<TS> M = multibody::crba(B, P);
      const std::vector<TS> cg =
          multibody::inverse_dynamics(B, P, model.gravity, qd.data(), static_cast<const TS*>(nullptr), true);
      const std::vector<double> v = evaluate(tape, leaves);
      Data data(model);
      const Eigen::MatrixXd Me = mass_matrix(model, data, qv);
      const Eigen::VectorXd cge = bias_forces(model, data, qv, qdv);
      Eigen::MatrixXd Mt(n, n);
      Eigen::VectorXd cgt(n);
      for (int i = 0; i < n; ++i) {
        cgt[i] = v[static_cast<std::size_t>(cg[i].id)];
        for (int j = 0; j < n; ++j) Mt(i, j) = v[static_cast<std::size_t>(M[i * n + j].id)];
      }
      const double e = std::max(test::rel_diff(Mt, Me, 1.0), test::rel_diff(cgt, cge, 1.0));
      worst = std::max(worst, e);
      EXPECT_LT(e, 1e-12) << "dof " << dof << ", variant " << variant;
    }
  }
  std::printf("tape CRBA and Newton-Euler vs the engine, 30 random models of 1-10 joints: worst %.1e\n", worst);
}
}  // namespace
}  // namespace refdyn::symbolic_detail
