#pragma once
// Private to the generator's writers (emit_c.cpp: C99; emit.cpp: LaTeX and JSON): one printer
// over GiNaC expressions with three dialects.
#include "../expression/internal.hpp"
#include "refdyn/common/error.hpp"

#include <ginac/ginac.h>

#include <cstdio>
#include <functional>
#include <map>
#include <string>

namespace refdyn::symbolic_detail {

using GiNaC::ex;
using GiNaC::is_a;

enum class Dialect { C, Latex, Text };

inline std::string double_text(double v, int digits) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  std::string s = buf;
  return s;
}

/// Prints GiNaC expressions. `leaf` names symbols; `shared` (C only) returns the name of a
/// common sub-expression or an empty string.
class Printer {
 public:
  Printer(Dialect d, std::function<std::string(const GiNaC::symbol&)> leaf) : d_(d), leaf_(std::move(leaf)) {}
  std::function<std::string(const ex&)> shared;  // C: temporaries
  long operations = 0;

  /// A term printed with a leading minus (negative number, or product with a negative coefficient).
  static bool negative_term(const ex& t) {
    if (is_a<GiNaC::numeric>(t)) return GiNaC::ex_to<GiNaC::numeric>(t).is_negative();
    if (is_a<GiNaC::mul>(t)) {
      const ex c = t.op(t.nops() - 1);
      return is_a<GiNaC::numeric>(c) && GiNaC::ex_to<GiNaC::numeric>(c).is_negative();
    }
    return false;
  }
  /// Texts of nodes already printed (LaTeX: printing a shared graph once per node).
  std::map<ex, std::string, GiNaC::ex_is_less>* memo = nullptr;

  std::string print(const ex& e) {
    if (shared) {
      const std::string s = shared(e);
      if (!s.empty()) return s;
    }
    if (memo) {
      const auto it = memo->find(e);
      if (it != memo->end()) return it->second;
    }
    std::string text = print_node(e);
    if (memo && !is_a<GiNaC::symbol>(e) && !is_a<GiNaC::numeric>(e)) memo->emplace(e, text);
    return text;
  }
  /// The node itself (children through print()).
  std::string print_node(const ex& e) {
    if (is_a<GiNaC::numeric>(e)) return number(GiNaC::ex_to<GiNaC::numeric>(e));
    if (is_a<GiNaC::symbol>(e)) return leaf_(GiNaC::ex_to<GiNaC::symbol>(e));
    if (is_a<GiNaC::constant>(e)) {
      if (d_ == Dialect::Latex) return "\\pi";
      if (d_ == Dialect::Text) return "pi";
      return double_text(GiNaC::ex_to<GiNaC::numeric>(e.evalf()).to_double(), 17);
    }
    if (is_a<GiNaC::add>(e)) return sum(e);
    if (is_a<GiNaC::mul>(e)) return product(e);
    if (is_a<GiNaC::power>(e)) return power(e.op(0), e.op(1));
    if (is_a<GiNaC::function>(e)) return function(e);
    throw Error("generate: cannot print the expression " + expr_detail::to_text(e));
  }

 private:
  std::string number(const GiNaC::numeric& x) {
    std::string s;
    if (x.is_integer() && GiNaC::abs(x) < GiNaC::numeric(1L << 52)) {
      s = std::to_string(x.to_long());
      if (d_ == Dialect::C) s += ".0";
    } else if (x.is_rational() && d_ == Dialect::Latex && GiNaC::abs(x.numer()) < 100000 && x.denom() < 100000) {
      const GiNaC::numeric a = GiNaC::abs(x);
      s = "\\tfrac{" + std::to_string(a.numer().to_long()) + "}{" + std::to_string(a.denom().to_long()) + "}";
      if (x.is_negative()) s = "-" + s;
    } else {
      s = double_text(x.to_double(), d_ == Dialect::Latex ? 6 : 17);
      if (d_ == Dialect::Latex) {
        const auto e = s.find('e');
        if (e != std::string::npos) s = s.substr(0, e) + " \\cdot 10^{" + std::to_string(std::stoi(s.substr(e + 1))) + "}";
      }
    }
    return x.is_negative() && d_ != Dialect::Latex ? "(" + s + ")" : s;
  }
  /// e as an operand of a product or power: parenthesised unless atomic.
  /// in_product: a power needs no parentheses as a factor of a product (it binds tighter).
  std::string factor(const ex& e, bool in_product = false) {
    const std::string s = print(e);
    const bool atomic = is_a<GiNaC::symbol>(e) || is_a<GiNaC::function>(e) || is_a<GiNaC::constant>(e) ||
                        (is_a<GiNaC::numeric>(e) && !GiNaC::ex_to<GiNaC::numeric>(e).is_negative()) ||
                        (shared && !shared(e).empty()) ||
                        ((d_ == Dialect::C || in_product) && is_a<GiNaC::power>(e));
    if (atomic) return s;
    return d_ == Dialect::Latex ? "\\left(" + s + "\\right)" : "(" + s + ")";
  }
  std::string sum(const ex& e) {
    std::string s;
    for (size_t i = 0; i < e.nops(); ++i) {
      const ex t = e.op(i);
      const bool neg = negative_term(t);
      const std::string body = print(neg ? ex(-t) : t);
      if (i == 0) s = neg ? "-" + body : body;
      else s += (neg ? " - " : " + ") + body;
      if (i) ++operations;
    }
    return s;
  }
  std::string product(const ex& e) {
    std::vector<std::string> num, den;
    std::string sign;
    for (size_t i = 0; i < e.nops(); ++i) {
      const ex f = e.op(i);
      if (is_a<GiNaC::numeric>(f)) {
        GiNaC::numeric c = GiNaC::ex_to<GiNaC::numeric>(f);
        if (c.is_negative()) {
          sign = "-";
          c = -c;
        }
        if (c.is_equal(1)) continue;
        if (c.is_rational() && !c.is_integer() && d_ != Dialect::Latex && GiNaC::abs(c.numer()) < 100000 &&
            c.denom() < 100000) {
          if (!c.numer().is_equal(1)) num.push_back(number(c.numer()));
          den.push_back(number(c.denom()));
        } else {
          num.insert(num.begin(), number(c));
        }
        continue;
      }
      if (is_a<GiNaC::power>(f) && is_a<GiNaC::numeric>(f.op(1)) &&
          GiNaC::ex_to<GiNaC::numeric>(f.op(1)).is_negative() && !(shared && !shared(f).empty())) {
        const ex inv = GiNaC::power(f.op(0), -f.op(1)).hold();
        den.push_back(GiNaC::ex_to<GiNaC::numeric>(f.op(1)).is_equal(-1) ? factor(f.op(0), true) : factor(inv, true));
        if (!GiNaC::ex_to<GiNaC::numeric>(f.op(1)).is_equal(-1)) ++operations;
        continue;
      }
      num.push_back(factor(f, true));
    }
    const std::string times = d_ == Dialect::Latex ? " " : "*";
    auto join = [&](const std::vector<std::string>& v) {
      std::string s;
      for (size_t i = 0; i < v.size(); ++i) s += (i ? times : "") + v[i];
      if (v.size() > 1) operations += static_cast<long>(v.size()) - 1;
      return s;
    };
    std::string n = num.empty() ? (d_ == Dialect::C ? "1.0" : "1") : join(num);
    if (den.empty()) return sign + n;
    ++operations;
    const std::string d = join(den);
    if (d_ == Dialect::Latex) return sign + "\\frac{" + n + "}{" + d + "}";
    return sign + (num.size() > 1 ? "(" + n + ")" : n) + "/" + (den.size() > 1 ? "(" + d + ")" : d);
  }
  std::string power(const ex& b, const ex& p) {
    ++operations;
    if (p.is_equal(GiNaC::numeric(1, 2))) return d_ == Dialect::Latex ? "\\sqrt{" + print(b) + "}" : "sqrt(" + print(b) + ")";
    if (p.is_equal(GiNaC::numeric(-1, 2)))
      return d_ == Dialect::Latex ? "\\frac{1}{\\sqrt{" + print(b) + "}}" : (d_ == Dialect::C ? "1.0/" : "1/") + std::string("sqrt(") + print(b) + ")";
    if (d_ == Dialect::C) {
      if (p.is_equal(-1)) return "1.0/" + factor(b);
      if (p.is_equal(2) && (is_a<GiNaC::symbol>(b) || (shared && !shared(b).empty())))
        return "(" + print(b) + "*" + print(b) + ")";
      return "pow(" + print(b) + ", " + print(p) + ")";
    }
    if (d_ == Dialect::Latex) return "{" + factor(b) + "}^{" + print(p) + "}";
    return factor(b) + "^" + factor(p);
  }
  std::string function(const ex& e) {
    ++operations;
    const auto& f = GiNaC::ex_to<GiNaC::function>(e);
    const unsigned s = f.get_serial();
    std::vector<std::string> a;
    for (size_t i = 0; i < e.nops(); ++i) a.push_back(print(e.op(i)));
    auto call = [&](const std::string& name) {
      std::string r = name + (d_ == Dialect::Latex ? "\\left(" : "(");
      for (size_t i = 0; i < a.size(); ++i) r += (i ? ", " : "") + a[i];
      return r + (d_ == Dialect::Latex ? "\\right)" : ")");
    };
    using namespace expr_detail;
    // The piecewise functions of the expression engine (expression.hpp), per dialect: the
    // expression language's own names, LaTeX operators, or the generated C file's static helpers.
    const int d = static_cast<int>(d_);  // C, Latex, Text
    static const char* const names[6][3] = {{"fabs", "", "abs"},
                                            {"rd_sgn", "\\operatorname{sgn}", ""},
                                            {"rd_min", "\\min", "min"},
                                            {"rd_max", "\\max", "max"},
                                            {"rd_step", "\\operatorname{step}", "step"},
                                            {"rd_clamp", "\\operatorname{clamp}", "clamp"}};
    const unsigned serials[6] = {serial_abs(), serial_sgn(), serial_min(), serial_max(), serial_step(), serial_clamp()};
    if (d_ == Dialect::Latex && s == serial_abs()) return "\\left|" + a[0] + "\\right|";
    if (d_ == Dialect::Text && s == serial_sgn()) return "if(" + a[0] + " >= 0, 1, -1)";
    for (int k = 0; k < 6; ++k)
      if (s == serials[k]) return call(names[k][d]);
    if (s == serial_if_lt() || s == serial_if_le()) {
      const bool lt = s == serial_if_lt();
      if (d_ == Dialect::Latex)
        return "\\begin{cases}" + a[2] + " & " + a[0] + (lt ? " < " : " \\le ") + a[1] + "\\\\ " + a[3] +
               " & \\text{otherwise}\\end{cases}";
      if (d_ == Dialect::Text) return "if(" + a[0] + (lt ? " < " : " <= ") + a[1] + ", " + a[2] + ", " + a[3] + ")";
      return "(" + a[0] + (lt ? " < " : " <= ") + a[1] + " ? " + a[2] + " : " + a[3] + ")";
    }
    if (d_ == Dialect::Text) return call(f.get_name());
    if (d_ == Dialect::Latex) {
      const std::string name = f.get_name();
      static const char* known[] = {"sin", "cos", "tan", "sinh", "cosh", "tanh", "exp", "log"};
      for (const char* k : known)
        if (name == k) return call(std::string("\\") + k);
      if (name == "asin" || name == "acos" || name == "atan") return call("\\arc" + name.substr(1));
      return call("\\operatorname{" + name + "}");
    }
    const std::string name = f.get_name();
    if (name == "atan2") return call("atan2");
    if (name == "abs") return call("fabs");
    return call(name);
  }

  Dialect d_;
  std::function<std::string(const GiNaC::symbol&)> leaf_;
};

/// How often each compound node occurs in a shared expression graph (C: CSE; LaTeX: named
/// sub-expressions).
using ExCount = std::map<ex, int, GiNaC::ex_is_less>;

inline void count_uses(const ex& e, ExCount& count) {
  if (is_a<GiNaC::symbol>(e) || is_a<GiNaC::numeric>(e) || is_a<GiNaC::constant>(e)) return;
  if (count[e]++ > 0) return;
  for (size_t i = 0; i < e.nops(); ++i) count_uses(e.op(i), count);
}

}  // namespace refdyn::symbolic_detail
