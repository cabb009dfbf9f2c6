// Expression engine: printing a GiNaC expression back in refdyn's own expression syntax
// (source_text). Two reasons not to use GiNaC's printer for text that users see or that is
// parsed again (derivative texts, `differentiate: true`):
//  - GiNaC orders the operands of sums and products by hashes that depend on the process
//    (addresses), so its printout of one expression changes from run to run; here they are
//    ordered by their own text;
//  - GiNaC prints the piecewise functions under their registered names (rd_abs, rd_sgn,
//    rd_if_le, ...), which the parser does not read; here they are written as the user writes
//    them (abs, if(x <= y, a, b), ...), with the same values and derivatives.
#include "internal.hpp"

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

namespace refdyn {
namespace expr_detail {

using GiNaC::ex;

namespace {

// Binding strength of a printed form: a form weaker than its context is parenthesized.
enum Prec : int { kSum = 1, kProduct = 2, kPower = 4, kAtom = 5 };

struct Printed {
  std::string text;
  int prec;
};

std::string numeric_text(const GiNaC::numeric& n) {
  std::ostringstream os;
  os << ex(n);
  return os.str();
}

Printed print(const ex& e);

std::string wrap(const Printed& p, int context) { return p.prec < context ? "(" + p.text + ")" : p.text; }

Printed print_numeric(const GiNaC::numeric& n) {
  const std::string t = numeric_text(n);
  const bool plain = t.find_first_of("-/") == std::string::npos;  // a sign or a fraction binds like a sum
  return {t, plain ? kAtom : kSum};
}

std::string joined(std::vector<std::string> parts, const char* sep) {
  std::sort(parts.begin(), parts.end());
  std::string out;
  for (std::size_t i = 0; i < parts.size(); ++i) out += (i ? sep : "") + parts[i];
  return out;
}

bool negative_number(const ex& e) {
  return GiNaC::is_a<GiNaC::numeric>(e) && GiNaC::ex_to<GiNaC::numeric>(e).is_real() &&
         GiNaC::ex_to<GiNaC::numeric>(e).is_negative();
}

Printed print_power(const ex& base, const ex& exponent) {
  if (exponent.is_equal(GiNaC::numeric(1, 2))) return {"sqrt(" + print(base).text + ")", kAtom};
  const Printed b = print(base), x = print(exponent);
  // The base binds tighter than ^ only as an atom; the exponent is parenthesized unless atomic.
  return {wrap(b, kAtom) + "^" + wrap(x, kAtom), kPower};
}

// A product: sign, numeric coefficient, the factors with a positive exponent, then "/" and
// those with a negative numeric exponent (written with the positive one).
Printed print_product(const std::vector<ex>& factors) {
  GiNaC::numeric coefficient(1);
  std::vector<std::string> up, down;
  for (const ex& f : factors) {
    if (GiNaC::is_a<GiNaC::numeric>(f)) {
      coefficient *= GiNaC::ex_to<GiNaC::numeric>(f);
    } else if (GiNaC::is_a<GiNaC::power>(f) && negative_number(f.op(1))) {
      const ex positive = -f.op(1);
      down.push_back(positive.is_equal(1) ? wrap(print(f.op(0)), kPower) : wrap(print_power(f.op(0), positive), kPower));
    } else {
      up.push_back(wrap(print(f), kProduct));
    }
  }
  std::string sign;
  if (coefficient.is_real() && coefficient.is_negative()) {
    sign = "-";
    coefficient = -coefficient;
  }
  std::string text;
  if (!coefficient.is_equal(GiNaC::numeric(1)) || up.empty())
    text = wrap(print_numeric(coefficient), kAtom);
  if (!up.empty()) text += (text.empty() ? "" : "*") + joined(up, "*");
  if (!down.empty()) text += "/" + (down.size() == 1 ? down[0] : "(" + joined(down, "*") + ")");
  return {sign + text, sign.empty() ? kProduct : kSum};
}

Printed print_sum(const ex& e) {
  std::vector<std::string> terms;
  for (std::size_t i = 0; i < e.nops(); ++i) terms.push_back(print(e.op(i)).text);
  std::sort(terms.begin(), terms.end(), [](const std::string& a, const std::string& b) {
    // Positive terms first, then by text: a - b rather than -b + a.
    const bool na = !a.empty() && a[0] == '-', nb = !b.empty() && b[0] == '-';
    return na != nb ? nb : a < b;
  });
  std::string out;
  for (std::size_t i = 0; i < terms.size(); ++i) {
    const std::string& t = terms[i];
    if (i == 0) out = t;
    else if (t[0] == '-') out += " - " + t.substr(1);
    else out += " + " + t;
  }
  return {out, kSum};
}

Printed print_function(const ex& e) {
  const unsigned serial = GiNaC::ex_to<GiNaC::function>(e).get_serial();
  auto arg = [&](std::size_t i) { return print(e.op(i)).text; };
  if (serial == serial_if_lt() || serial == serial_if_le())
    return {"if(" + arg(0) + (serial == serial_if_lt() ? " < " : " <= ") + arg(1) + ", " + arg(2) + ", " + arg(3) + ")",
            kAtom};
  if (serial == serial_sgn()) return {"if(" + arg(0) + " < 0, -1, 1)", kAtom};  // the tape's Sign: −1 below 0, else 1
  std::string name = GiNaC::ex_to<GiNaC::function>(e).get_name();
  if (serial == serial_abs()) name = "abs";
  else if (serial == serial_min()) name = "min";
  else if (serial == serial_max()) name = "max";
  else if (serial == serial_step()) name = "step";
  else if (serial == serial_clamp()) name = "clamp";
  std::string out = name + "(";
  for (std::size_t i = 0; i < e.nops(); ++i) out += (i ? ", " : "") + arg(i);
  return {out + ")", kAtom};
}

Printed print(const ex& e) {
  if (GiNaC::is_a<GiNaC::numeric>(e)) return print_numeric(GiNaC::ex_to<GiNaC::numeric>(e));
  if (GiNaC::is_a<GiNaC::symbol>(e)) return {GiNaC::ex_to<GiNaC::symbol>(e).get_name(), kAtom};
  if (GiNaC::is_a<GiNaC::add>(e)) return print_sum(e);
  if (GiNaC::is_a<GiNaC::mul>(e)) {
    std::vector<ex> factors;
    for (std::size_t i = 0; i < e.nops(); ++i) factors.push_back(e.op(i));
    return print_product(factors);
  }
  if (GiNaC::is_a<GiNaC::power>(e)) {
    if (negative_number(e.op(1))) return print_product({e});  // x^(-2) as 1/x^2
    return print_power(e.op(0), e.op(1));
  }
  if (GiNaC::is_a<GiNaC::function>(e)) return print_function(e);
  if (e.is_equal(GiNaC::Pi)) return {"pi", kAtom};
  return {to_text(e), kAtom};  // anything else (not produced from the parser's forms): GiNaC's own text
}

}  // namespace

std::string source_text(const ex& e) { return print(e).text; }

}  // namespace expr_detail
}  // namespace refdyn
