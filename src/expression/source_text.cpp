// Expression engine: printing a GiNaC expression back in refdyn's own expression syntax
// (source_text). Two reasons not to use GiNaC's printer for text that users see or that is
// parsed again (derivative texts, `differentiate: true`):
//  - GiNaC orders the operands of sums and products by hashes that depend on the process
//    (addresses), and keeps a sum factor in either orientation (−(b − a) or (a − b)), so its
//    printout of one expression changes from run to run; here operands are ordered by their own
//    text and a sum factor is oriented by its first term (flip);
//  - GiNaC prints the piecewise functions under their registered names (rd_abs, rd_sgn,
//    rd_if_le, ...), which the parser does not read; here they are written as the user writes
//    them (abs, if(x <= y, a, b), ...), with the same values and derivatives.
#include "internal.hpp"

#include "refdyn/expression/formula.hpp"

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

namespace refdyn {
namespace expr_detail {

using GiNaC::ex;

namespace {

// The printed forms are Formulas (formula.hpp): their operators hold the language's binding
// rules (which operand takes parentheses), the same ones the laws' text forms are written with.
using F = Formula;

std::string numeric_text(const GiNaC::numeric& n) {
  std::ostringstream os;
  os << ex(n);
  return os.str();
}

/// A number as GiNaC writes it: "1/2" binds like a quotient, "-3" like a negation.
F print_numeric(const GiNaC::numeric& n) {
  const std::string t = numeric_text(n);
  return F(t, t.find('/') != std::string::npos ? F::kProduct : t[0] == '-' ? F::kNegation : F::kAtom);
}

bool negative_number(const ex& e) {
  return GiNaC::is_a<GiNaC::numeric>(e) && GiNaC::ex_to<GiNaC::numeric>(e).is_real() &&
         GiNaC::ex_to<GiNaC::numeric>(e).is_negative();
}

/// A term of a sum as ± magnitude: a product carries the sign of its coefficient, a number its own.
struct Term {
  bool negative;
  F magnitude;
  std::string key() const { return (negative ? "-" : "") + magnitude.text(); }
};

F print(const ex& e);
Term term(const ex& e);

/// The terms of a sum, each printed once.
std::vector<Term> terms(const ex& sum) {
  std::vector<Term> out;
  for (std::size_t i = 0; i < sum.nops(); ++i) out.push_back(term(sum.op(i)));
  return out;
}

/// Whether a sum factor is written negated, −(b − a) as (a − b) with the sign moved out: when
/// its first term by magnitude is negative. GiNaC keeps either orientation of a sum factor,
/// depending on its per-process term order; this fixes one.
bool leads_negative(const std::vector<Term>& ts) {
  return std::min_element(ts.begin(), ts.end(), [](const Term& a, const Term& b) {
           return a.magnitude.text() < b.magnitude.text();
         })->negative;
}

/// The sum of the terms, every sign flipped when `negate`: positive terms first, then by text
/// (a − b rather than −b + a).
F join(std::vector<Term> ts, bool negate) {
  for (Term& t : ts) t.negative = t.negative != negate;
  std::sort(ts.begin(), ts.end(), [](const Term& a, const Term& b) {
    return a.negative != b.negative ? b.negative : a.key() < b.key();
  });
  F out = ts[0].negative ? -ts[0].magnitude : ts[0].magnitude;
  for (std::size_t i = 1; i < ts.size(); ++i) out = ts[i].negative ? out - ts[i].magnitude : out + ts[i].magnitude;
  return out;
}

/// A factor of a product: a sum oriented by leads_negative when `may_flip` (the sign it moves
/// out toggles `negative` when `odd`), anything else as printed.
F factor(const ex& f, bool may_flip, bool odd, bool& negative) {
  if (!GiNaC::is_a<GiNaC::add>(f)) return print(f);
  const std::vector<Term> ts = terms(f);
  const bool flip = may_flip && leads_negative(ts);
  if (flip && odd) negative = !negative;
  return join(ts, flip);
}

/// base^exponent: a sum base oriented where the exponent is an integer (an even one absorbs the
/// sign, an odd one moves it into `negative`); under any other exponent GiNaC's orientation stays.
F print_power(const ex& base, const ex& exponent, bool& negative) {
  const bool integer = GiNaC::is_a<GiNaC::numeric>(exponent) && GiNaC::ex_to<GiNaC::numeric>(exponent).is_integer();
  const F b = factor(base, integer, integer && GiNaC::ex_to<GiNaC::numeric>(exponent).is_odd(), negative);
  if (exponent.is_equal(GiNaC::numeric(1, 2))) return call("sqrt", {b});
  if (exponent.is_equal(1)) return b;
  return pow(b, print(exponent));
}

/// A product: numeric coefficient, the factors with a positive exponent, then "/" and those with
/// a negative numeric exponent (written with the positive one), each group in text order.
Term product(const std::vector<ex>& factors) {
  GiNaC::numeric coefficient(1);
  bool negative = false;
  std::vector<F> up, down;
  for (const ex& f : factors) {
    if (GiNaC::is_a<GiNaC::numeric>(f)) {
      coefficient *= GiNaC::ex_to<GiNaC::numeric>(f);
    } else if (GiNaC::is_a<GiNaC::power>(f)) {
      const bool below = negative_number(f.op(1));
      (below ? down : up).push_back(print_power(f.op(0), below ? ex(-f.op(1)) : f.op(1), negative));
    } else {
      up.push_back(factor(f, true, true, negative));
    }
  }
  if (coefficient.is_real() && coefficient.is_negative()) {
    negative = !negative;
    coefficient = -coefficient;
  }
  auto in_order = [](std::vector<F>& fs, F::Binding context) {
    std::sort(fs.begin(), fs.end(), [context](const F& a, const F& b) {
      return operand_text(a, context) < operand_text(b, context);
    });
  };
  in_order(up, F::kProduct);
  in_order(down, F::kPower);
  std::vector<F> numerator;
  if (!coefficient.is_equal(GiNaC::numeric(1)) || up.empty())
    numerator.push_back(F(operand_text(print_numeric(coefficient), F::kAtom), F::kAtom));
  numerator.insert(numerator.end(), up.begin(), up.end());
  F out = numerator[0];
  for (std::size_t i = 1; i < numerator.size(); ++i) out = out * numerator[i];
  if (!down.empty()) {
    F denominator = down[0];
    for (std::size_t i = 1; i < down.size(); ++i) denominator = denominator * down[i];
    out = out / denominator;
  }
  return {negative, out};
}

Term term(const ex& e) {
  if (GiNaC::is_a<GiNaC::mul>(e)) {
    std::vector<ex> factors;
    for (std::size_t i = 0; i < e.nops(); ++i) factors.push_back(e.op(i));
    return product(factors);
  }
  if (GiNaC::is_a<GiNaC::power>(e)) return product({e});  // x^(-2) as 1/x^2; a sum base oriented
  if (negative_number(e)) return {true, print_numeric(-GiNaC::ex_to<GiNaC::numeric>(e))};
  return {false, print(e)};
}

F print_function(const ex& e) {
  const unsigned serial = GiNaC::ex_to<GiNaC::function>(e).get_serial();
  auto arg = [&](std::size_t i) { return print(e.op(i)).text(); };
  if (serial == serial_if_lt() || serial == serial_if_le())
    return F("if(" + arg(0) + (serial == serial_if_lt() ? " < " : " <= ") + arg(1) + ", " + arg(2) + ", " + arg(3) + ")",
             F::kAtom);
  if (serial == serial_sgn()) return F("if(" + arg(0) + " < 0, -1, 1)", F::kAtom);  // the tape's Sign: −1 below 0, else 1
  std::string name = GiNaC::ex_to<GiNaC::function>(e).get_name();
  if (serial == serial_abs()) name = "abs";
  else if (serial == serial_min()) name = "min";
  else if (serial == serial_max()) name = "max";
  else if (serial == serial_step()) name = "step";
  else if (serial == serial_clamp()) name = "clamp";
  std::string out = name + "(";
  for (std::size_t i = 0; i < e.nops(); ++i) out += (i ? ", " : "") + arg(i);
  return F(out + ")", F::kAtom);
}

F print(const ex& e) {
  if (GiNaC::is_a<GiNaC::numeric>(e)) return print_numeric(GiNaC::ex_to<GiNaC::numeric>(e));
  if (GiNaC::is_a<GiNaC::symbol>(e)) return F::variable(GiNaC::ex_to<GiNaC::symbol>(e).get_name());
  if (GiNaC::is_a<GiNaC::add>(e)) return join(terms(e), false);
  if (GiNaC::is_a<GiNaC::mul>(e) || GiNaC::is_a<GiNaC::power>(e)) {
    const Term t = term(e);
    return t.negative ? -t.magnitude : t.magnitude;
  }
  if (GiNaC::is_a<GiNaC::function>(e)) return print_function(e);
  if (e.is_equal(GiNaC::Pi)) return F::variable("pi");
  return F(to_text(e), F::kAtom);  // anything else (not produced from the parser's forms): GiNaC's own text
}

}  // namespace

std::string source_text(const ex& e) { return print(e).text(); }

}  // namespace expr_detail
}  // namespace refdyn
