// The canonical graph the generated code is written from (src/symbolic/trace.hpp, private to the
// generator): expressions that GiNaC may build in different forms from run to run — the order of
// its operands follows address-seeded hashes, and some simplifications follow that order — are
// one node. The forms are built here with hold(), which keeps GiNaC from evaluating them.
// The whole-program check (refdyn generate twice, byte-identical files): symbolic_test.cpp.
#include "../src/symbolic/trace.hpp"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace refdyn::symbolic_detail
