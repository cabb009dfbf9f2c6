// Expression engine, stage 3: the tape compiler. GiNaC expressions -> SSA with CSE and
// constant folding -> peephole fusion -> liveness and register allocation -> the program the
// interpreter runs; set-up of the closed-form quadratic kernel.
#include "internal.hpp"

#include "refdyn/common/text.hpp"

#include <algorithm>
#include <bit>
#include <functional>
#include <initializer_list>
#include <queue>
#include <set>
#include <tuple>
#include <unordered_map>
#include <unordered_set>

namespace refdyn {
namespace expr_detail {

using GiNaC::ex;

namespace {

struct Operand {
  bool is_const = false;
  double c = 0.0;
  std::uint32_t v = 0;  // SSA value id
  static Operand constant(double x) { return {true, x, 0}; }
  static Operand value(std::uint32_t id) { return {false, 0.0, id}; }
};

struct SsaInstr {
  Op op;
  std::uint32_t dst, a, b;  // b: second input, or second output for SinCos
  double c, d;
};

class Compiler {
 public:
  /// Thrown by a compiler without CSE when it has visited `budget` nodes.
  struct OverBudget {};

  Compiler(const std::vector<GiNaC::realsymbol>& syms, bool cse, std::size_t budget = 0)
      : syms_(syms), cse_(cse), budget_(budget) {}

  /// Registers sin/cos arguments of all targets so that sin(u), cos(u) pairs fuse to sincos.
  void scan(const ex& e) {
    // Each shared sub-expression once (derivatives share most of their structure).
    if (!scanned_.insert(key(e)).second) return;
    if (GiNaC::is_a<GiNaC::function>(e)) {
      const std::string name = GiNaC::ex_to<GiNaC::function>(e).get_name();
      if (name == "sin") sin_args_.insert(e.op(0));
      if (name == "cos") cos_args_.insert(e.op(0));
    }
    for (std::size_t i = 0; i < e.nops(); ++i) scan(e.op(i));
  }

  Operand compile(const ex& e) {
    // Without CSE every occurrence is compiled again: the walk is over the tree expansion of
    // a derivative DAG, which can be far larger than the DAG (bounded by the budget).
    if (!cse_ && budget_ && ++visits_ > budget_) throw OverBudget{};
    if (cse_) {
      // Fast path: this very object was compiled before (no structural comparison).
      auto p = by_object_.find(&GiNaC::ex_to<GiNaC::basic>(e));
      if (p != by_object_.end()) return p->second;
      auto it = memo_.find(e);
      if (it != memo_.end()) {
        by_object_.emplace(key(e), it->second);
        return it->second;
      }
    }
    Operand r = compile_uncached(e);
    if (cse_) {
      memo_.emplace(e, r);
      by_object_.emplace(key(e), r);
    }
    return r;
  }

  std::size_t size() const { return code_.size(); }
  std::uint32_t num_values() const { return next_value_; }
  const std::vector<SsaInstr>& code() const { return code_; }
  const std::vector<std::pair<std::uint32_t, int>>& loads() const { return loads_; }

 private:
  std::uint32_t new_value() { return next_value_++; }

  /// The object behind e, kept alive so that its address stays a valid key.
  const GiNaC::basic* key(const ex& e) {
    alive_.push_back(e);
    return &GiNaC::ex_to<GiNaC::basic>(e);
  }

  /// has_symbol, memoised per object: derivative trees share sub-expressions, and an
  /// unmemoised walk from every node would cost (tree size) x (depth) or worse.
  bool has_sym(const ex& e) {
    const GiNaC::basic* p = &GiNaC::ex_to<GiNaC::basic>(e);
    auto it = has_sym_.find(p);
    if (it != has_sym_.end()) return it->second;
    bool r = GiNaC::is_a<GiNaC::symbol>(e);
    for (std::size_t i = 0; i < e.nops() && !r; ++i) r = has_sym(e.op(i));
    has_sym_.emplace(key(e), r);
    return r;
  }

  Operand emit(Op op, std::uint32_t a, std::uint32_t b = 0, double c = 0.0, double d = 0.0) {
    using Key = std::tuple<int, std::uint32_t, std::uint32_t, std::uint64_t, std::uint64_t>;
    Key key{static_cast<int>(op), a, info(op).inputs >= 2 ? b : 0u,
            std::bit_cast<std::uint64_t>(c), std::bit_cast<std::uint64_t>(d)};
    if (cse_) {
      auto it = hashcons_.find(key);
      if (it != hashcons_.end()) return Operand::value(it->second);
    }
    std::uint32_t dst = new_value();
    code_.push_back({op, dst, a, b, c, d});
    if (cse_) hashcons_.emplace(key, dst);
    return Operand::value(dst);
  }

  std::uint32_t reg(const Operand& o) {
    if (!o.is_const) return o.v;
    return emit(Op::Const, 0, 0, o.c).v;
  }

  /// A function of one argument (immediates c = 1, d = 0: the affine argument is the identity).
  Operand function(Op op, const Operand& a) {
    if (a.is_const) return Operand::constant(apply(op, a.c, 0.0, 1.0, 0.0));
    return emit(op, a.v, 0, 1.0, 0.0);
  }

  Operand add(const Operand& a, const Operand& b) {
    if (a.is_const && b.is_const) return Operand::constant(a.c + b.c);
    if (a.is_const) return a.c == 0.0 ? b : emit(Op::AddC, b.v, 0, a.c);
    if (b.is_const) return b.c == 0.0 ? a : emit(Op::AddC, a.v, 0, b.c);
    return emit(Op::Add, std::min(a.v, b.v), std::max(a.v, b.v));
  }

  Operand scale(const Operand& a, double c) {
    if (a.is_const) return Operand::constant(a.c * c);
    if (c == 1.0) return a;
    if (c == -1.0) return emit(Op::Neg, a.v);
    return emit(Op::MulC, a.v, 0, c);
  }

  Operand mul(const Operand& a, const Operand& b) {
    if (a.is_const) return scale(b, a.c);
    if (b.is_const) return scale(a, b.c);
    if (a.v == b.v) return emit(Op::Sq, a.v);
    return emit(Op::Mul, std::min(a.v, b.v), std::max(a.v, b.v));
  }

  Operand div(const Operand& a, const Operand& b) {
    if (b.is_const) return scale(a, 1.0 / b.c);
    if (a.is_const) return emit(Op::RDivC, b.v, 0, a.c);
    return emit(Op::Div, a.v, b.v);
  }

  Operand powi(const Operand& b, long n) {  // n >= 1
    if (n == 1) return b;
    if (cse_) {
      auto it = powi_.find({b.v, n});
      if (it != powi_.end()) return Operand::value(it->second);
    }
    Operand r = n % 2 == 0 ? emit(Op::Sq, powi(b, n / 2).v) : mul(powi(b, n - 1), b);
    if (cse_) powi_[{b.v, n}] = r.v;
    return r;
  }

  /// base^p for a numeric exponent p, base a register.
  Operand pow_numeric(const Operand& base, double p) {
    if (p == std::trunc(p) && std::fabs(p) <= 64) {
      long n = static_cast<long>(p);
      if (n == 0) return Operand::constant(1.0);
      if (n > 0) return powi(base, n);
      return emit(Op::RDivC, powi(base, -n).v, 0, 1.0);
    }
    double twice = 2 * p;
    if (twice == std::trunc(twice) && std::fabs(p) <= 64) {
      long m = static_cast<long>(twice);  // odd
      long am = m < 0 ? -m : m;
      Operand s = function(Op::Sqrt, base);
      Operand r = am == 1 ? s : mul(powi(base, (am - 1) / 2), s);
      return m > 0 ? r : emit(Op::RDivC, r.v, 0, 1.0);
    }
    return emit(Op::PowC, base.v, 0, p);
  }

  /// Splits c*rest; c numeric (constant factors folded), rest has symbols (or is 1).
  std::pair<double, ex> split_coefficient(const ex& e) {
    if (GiNaC::is_a<GiNaC::mul>(e)) {
      ex constant = 1, rest = 1;
      for (std::size_t i = 0; i < e.nops(); ++i) {
        if (has_sym(e.op(i)))
          rest *= e.op(i);
        else
          constant *= e.op(i);
      }
      return {constant_value(constant), rest};
    }
    return {1.0, e};
  }

  /// acc + c*r for operands that may be constants.
  Operand axpy(const Operand& acc, const Operand& r, double c) {
    if (r.is_const) return add(acc, Operand::constant(c * r.c));
    if (c == 1.0) return add(acc, r);
    if (acc.is_const) {
      if (c == -1.0) return emit(Op::RSubC, r.v, 0, acc.c);
      return acc.c == 0.0 ? scale(r, c) : emit(Op::Affine, r.v, 0, c, acc.c);
    }
    if (c == -1.0) return emit(Op::Sub, acc.v, r.v);
    return emit(Op::Axpy, acc.v, r.v, c);
  }

  Operand compile_add(const ex& e) {
    ex constant = 0;
    std::vector<std::pair<double, Operand>> terms;
    for (std::size_t i = 0; i < e.nops(); ++i) {
      const ex& term = e.op(i);
      if (!has_sym(term)) {
        constant += term;
        continue;
      }
      auto [c, rest] = split_coefficient(term);
      terms.push_back({c, compile(rest)});
    }
    Operand acc = Operand::constant(constant_value(constant));
    // Start from a term with coefficient 1 if there is one (saves a multiplication); the
    // constant is then added last, else folded into the first term (c*r + c0).
    auto first = std::find_if(terms.begin(), terms.end(), [](const auto& t) {
      return t.first == 1.0 && !t.second.is_const;
    });
    if (first != terms.end()) {
      Operand c0 = acc;
      acc = first->second;
      terms.erase(first);
      for (const auto& [c, r] : terms) acc = axpy(acc, r, c);
      return add(acc, c0);
    }
    for (const auto& [c, r] : terms) acc = axpy(acc, r, c);
    return acc;
  }

  Operand compile_mul(const ex& e) {
    ex constant = 1;
    std::vector<Operand> num, den;
    for (std::size_t i = 0; i < e.nops(); ++i) {
      const ex& f = e.op(i);
      if (!has_sym(f)) {
        constant *= f;
        continue;
      }
      if (GiNaC::is_a<GiNaC::power>(f) && GiNaC::is_a<GiNaC::numeric>(f.op(1)) &&
          !has_sym(f.op(1))) {
        const GiNaC::numeric& p = GiNaC::ex_to<GiNaC::numeric>(f.op(1));
        if (p.is_real() && p.is_negative()) {
          den.push_back(compile(GiNaC::pow(f.op(0), -p)));
          continue;
        }
      }
      num.push_back(compile(f));
    }
    double c = constant_value(constant);
    auto product = [&](const std::vector<Operand>& v) {
      Operand acc = v.front();
      for (std::size_t i = 1; i < v.size(); ++i) acc = mul(acc, v[i]);
      return acc;
    };
    if (num.empty() && den.empty()) return Operand::constant(c);
    if (num.empty()) return div(Operand::constant(c), product(den));
    Operand r = product(num);
    if (!den.empty()) r = div(r, product(den));
    return scale(r, c);
  }

  Operand compile_power(const ex& e) {
    const ex& b = e.op(0);
    const ex& p = e.op(1);
    if (!has_sym(p)) {
      double pv = constant_value(p);
      Operand base = compile(b);
      if (base.is_const) return Operand::constant(std::pow(base.c, pv));
      return pow_numeric(base, pv);
    }
    Operand expo = compile(p);
    if (!has_sym(b)) {  // c^u = exp(u log c)
      double bv = constant_value(b);
      if (bv > 0) return function(Op::Exp, scale(expo, std::log(bv)));
      return emit(Op::Pow, reg(Operand::constant(bv)), expo.v);
    }
    Operand base = compile(b);
    return emit(Op::Pow, reg(base), reg(expo));
  }

  /// x < y ? a : b (strict) or x <= y ? a : b: a 1/0 mask, then a select (no arithmetic on the
  /// branch not taken, so an infinite or NaN branch does not leak into the result).
  Operand compile_if(const ex& e, bool strict) {
    Operand x = compile(e.op(0)), y = compile(e.op(1));
    if (x.is_const && y.is_const)
      return compile(strict ? (x.c < y.c ? e.op(2) : e.op(3)) : (x.c <= y.c ? e.op(2) : e.op(3)));
    Operand mask = compare(strict, x, y);
    return select(mask, compile(e.op(2)), compile(e.op(3)));
  }

  /// mask ? a : b for compiled operands.
  Operand select(const Operand& mask, const Operand& a, const Operand& b) {
    if (mask.is_const) return mask.c != 0.0 ? a : b;
    if (a.is_const && b.is_const && a.c == 1.0 && b.c == 0.0) return mask;
    if (a.is_const && b.is_const && a.c == 0.0 && b.c == 1.0)
      return emit(Op::RSubC, mask.v, 0, 1.0);
    if (a.is_const == b.is_const && (a.is_const ? a.c == b.c : a.v == b.v)) return a;
    const std::uint32_t ra = reg(a), rb = reg(b);
    return emit(Op::Select, mask.v, ra, 0.0, select_else_bits(rb));
  }
  /// x < y (strict) or x <= y as a 1/0 mask.
  Operand compare(bool strict, const Operand& x, const Operand& y) {
    if (x.is_const && y.is_const)
      return Operand::constant((strict ? x.c < y.c : x.c <= y.c) ? 1.0 : 0.0);
    return emit(strict ? Op::CmpLt : Op::CmpLe, reg(x), reg(y));
  }

  Operand compile_function(const ex& e) {
    const unsigned serial = GiNaC::ex_to<GiNaC::function>(e).get_serial();
    if (serial == serial_min() || serial == serial_max()) {
      Operand a = compile(e.op(0)), b = compile(e.op(1));
      return serial == serial_min() ? select(compare(false, a, b), a, b)
                                    : select(compare(false, b, a), a, b);
    }
    if (serial == serial_step())
      return select(compare(false, Operand::constant(0.0), compile(e.op(0))),
                    Operand::constant(1.0), Operand::constant(0.0));
    if (serial == serial_clamp()) {
      Operand x = compile(e.op(0)), lo = compile(e.op(1)), hi = compile(e.op(2));
      return select(compare(true, x, lo), lo, select(compare(true, hi, x), hi, x));
    }
    if (serial == serial_if_lt()) return compile_if(e, true);
    if (serial == serial_if_le()) return compile_if(e, false);
    if (serial == serial_abs()) return function(Op::Abs, compile(e.op(0)));
    if (serial == serial_sgn()) return function(Op::Sign, compile(e.op(0)));
    const std::string name = GiNaC::ex_to<GiNaC::function>(e).get_name();
    if (name == "atan2") {
      Operand y = compile(e.op(0)), x = compile(e.op(1));
      return emit(Op::Atan2, reg(y), reg(x));
    }
    static const std::map<std::string, Op> kUnary = {
        {"sin", Op::Sin},     {"cos", Op::Cos},     {"tan", Op::Tan},   {"asin", Op::Asin},
        {"acos", Op::Acos},   {"atan", Op::Atan},   {"sinh", Op::Sinh}, {"cosh", Op::Cosh},
        {"tanh", Op::Tanh},   {"asinh", Op::Asinh}, {"acosh", Op::Acosh},
        {"atanh", Op::Atanh}, {"exp", Op::Exp},     {"log", Op::Log},   {"abs", Op::Abs},
    };
    auto it = kUnary.find(name);
    if (it == kUnary.end() || e.nops() != 1)
      throw BadConstant{"contains the function '" + name +
                            "', which the evaluator does not support",
                        to_text(e), false};
    const ex& arg = e.op(0);
    Operand a = compile(arg);
    if ((name == "sin" || name == "cos") && cse_ && sin_args_.count(arg) && cos_args_.count(arg)) {
      auto sc = sincos_.find(a.v);
      if (sc == sincos_.end()) {
        std::uint32_t s = new_value(), c = new_value();
        code_.push_back({Op::SinCos, s, a.v, c, 1.0, 0.0});
        sc = sincos_.emplace(a.v, std::make_pair(s, c)).first;
      }
      return Operand::value(name == "sin" ? sc->second.first : sc->second.second);
    }
    return function(it->second, a);
  }

  Operand compile_uncached(const ex& e) {
    if (!has_sym(e)) return Operand::constant(constant_value(e));
    if (GiNaC::is_a<GiNaC::symbol>(e)) {
      for (std::size_t i = 0; i < syms_.size(); ++i)
        if (e.is_equal(syms_[i])) {
          if (cse_ && var_value_.count(static_cast<int>(i)))
            return Operand::value(var_value_[static_cast<int>(i)]);
          std::uint32_t v = new_value();
          loads_.push_back({v, static_cast<int>(i)});
          var_value_[static_cast<int>(i)] = v;
          return Operand::value(v);
        }
      throw BadConstant{"contains the unknown symbol '" + to_text(e) + "'", to_text(e), false};
    }
    if (GiNaC::is_a<GiNaC::add>(e)) return compile_add(e);
    if (GiNaC::is_a<GiNaC::mul>(e)) return compile_mul(e);
    if (GiNaC::is_a<GiNaC::power>(e)) return compile_power(e);
    if (GiNaC::is_a<GiNaC::function>(e)) return compile_function(e);
    throw BadConstant{"contains '" + to_text(e) + "', which is not a real-valued expression",
                      to_text(e), false};
  }

  const std::vector<GiNaC::realsymbol>& syms_;
  bool cse_;
  std::size_t budget_ = 0, visits_ = 0;
  std::vector<SsaInstr> code_;
  std::vector<std::pair<std::uint32_t, int>> loads_;
  std::uint32_t next_value_ = 0;
  std::vector<ex> alive_;
  std::unordered_map<const GiNaC::basic*, bool> has_sym_;
  std::unordered_set<const GiNaC::basic*> scanned_;
  std::unordered_map<const GiNaC::basic*, Operand> by_object_;
  std::map<ex, Operand, GiNaC::ex_is_less> memo_;
  std::map<std::tuple<int, std::uint32_t, std::uint32_t, std::uint64_t, std::uint64_t>,
           std::uint32_t>
      hashcons_;
  std::map<std::pair<std::uint32_t, long>, std::uint32_t> powi_;
  std::map<std::uint32_t, std::pair<std::uint32_t, std::uint32_t>> sincos_;
  std::map<int, std::uint32_t> var_value_;
  std::set<ex, GiNaC::ex_is_less> sin_args_, cos_args_;
};

/// The compiled program before register allocation.
struct SsaProgram {
  int n = 0;
  std::vector<SsaInstr> code;
  std::vector<std::pair<std::uint32_t, int>> loads;  // value <- x[var]
  std::uint32_t num_values = 0;
  std::array<std::size_t, 3> stage_end{};
  Operand value;
  std::vector<std::pair<int, Operand>> grad;  // (i, entry), used variables only
  std::vector<std::pair<int, Operand>> hess;  // (i*n + j, entry), i <= j
};

/// Peephole fusion of common instruction pairs when the intermediate has no other use:
/// f(c*a + d) for a scaling/shift feeding a function, c*a*a + d, a + c*b*b, a + c*b + d.
void fuse(SsaProgram& prog) {
  std::vector<SsaInstr>& code = prog.code;
  std::vector<int> uses(prog.num_values, 0), producer(prog.num_values, -1);
  std::vector<bool> dead(code.size(), false);
  for (const SsaInstr& in : code) {
    int inputs = info(in.op).inputs;
    if (inputs >= 1) ++uses[in.a];
    if (inputs >= 2) ++uses[in.b];
    if (in.op == Op::Select) ++uses[select_else(in.d)];
  }
  auto output = [&](const Operand& o) {
    if (!o.is_const) ++uses[o.v];
  };
  output(prog.value);
  for (const auto& [k, o] : prog.grad) output(o);
  for (const auto& [k, o] : prog.hess) output(o);

  for (std::size_t i = 0; i < code.size(); ++i) {
    SsaInstr& in = code[i];
    // The producer of value v if this instruction is its only user.
    auto single = [&](std::uint32_t v) -> SsaInstr* {
      int p = producer[v];
      if (p < 0 || uses[v] != 1 || dead[p]) return nullptr;
      return &code[p];
    };
    auto absorb = [&](SsaInstr* p) { dead[p - code.data()] = true; };
    SsaInstr* p = nullptr;
    if (is_function(in.op) && in.c == 1.0 && in.d == 0.0 && (p = single(in.a))) {
      if (p->op == Op::MulC) {
        in = {in.op, in.dst, p->a, in.b, p->c, 0.0};
        absorb(p);
      } else if (p->op == Op::AddC) {
        in = {in.op, in.dst, p->a, in.b, 1.0, p->c};
        absorb(p);
      } else if (p->op == Op::Affine) {
        in = {in.op, in.dst, p->a, in.b, p->c, p->d};
        absorb(p);
      }
    } else if (in.op == Op::MulC && (p = single(in.a)) && p->op == Op::Sq) {
      in = {Op::SqAffine, in.dst, p->a, 0, in.c, 0.0};
      absorb(p);
    } else if (in.op == Op::AddC && (p = single(in.a))) {
      if (p->op == Op::Axpy) {
        in = {Op::AxpyC, in.dst, p->a, p->b, p->c, in.c};
        absorb(p);
      } else if (p->op == Op::MulC) {
        in = {Op::Affine, in.dst, p->a, 0, p->c, in.c};
        absorb(p);
      } else if (p->op == Op::Sq) {
        in = {Op::SqAffine, in.dst, p->a, 0, 1.0, in.c};
        absorb(p);
      } else if (p->op == Op::SqAffine && p->d == 0.0) {
        in = {Op::SqAffine, in.dst, p->a, 0, p->c, in.c};
        absorb(p);
      }
    } else if (in.op == Op::Affine && (p = single(in.a)) && p->op == Op::Sq) {
      in = {Op::SqAffine, in.dst, p->a, 0, in.c, in.d};
      absorb(p);
    } else if (in.op == Op::Axpy && (p = single(in.b)) && p->op == Op::Sq) {
      in = {Op::AxpySq, in.dst, in.a, p->a, in.c, 0.0};
      absorb(p);
    } else if (in.op == Op::Add) {
      if ((p = single(in.b)) && (p->op == Op::Sq || p->op == Op::MulC)) {
        in = {p->op == Op::Sq ? Op::AxpySq : Op::Axpy, in.dst, in.a, p->a,
              p->op == Op::Sq ? 1.0 : p->c, 0.0};
        absorb(p);
      } else if ((p = single(in.a)) && (p->op == Op::Sq || p->op == Op::MulC)) {
        in = {p->op == Op::Sq ? Op::AxpySq : Op::Axpy, in.dst, in.b, p->a,
              p->op == Op::Sq ? 1.0 : p->c, 0.0};
        absorb(p);
      }
    } else if (in.op == Op::Sub && (p = single(in.b)) && p->op == Op::MulC) {
      in = {Op::Axpy, in.dst, in.a, p->a, -p->c, 0.0};
      absorb(p);
    }
    if (in.op != Op::SinCos) producer[in.dst] = static_cast<int>(i);
  }

  std::vector<SsaInstr> kept;
  std::array<std::size_t, 3> ends{};
  for (std::size_t i = 0; i < code.size(); ++i) {
    if (!dead[i]) kept.push_back(code[i]);
    for (int s = 0; s < 3; ++s)
      if (i + 1 == prog.stage_end[s]) ends[s] = kept.size();
  }
  for (int s = 0; s < 3; ++s)
    if (prog.stage_end[s] == 0) ends[s] = 0;
  // Stages that emitted nothing keep the previous boundary.
  for (int s = 1; s < 3; ++s)
    if (prog.stage_end[s] == prog.stage_end[s - 1]) ends[s] = ends[s - 1];
  prog.code = std::move(kept);
  prog.stage_end = ends;
}

/// Liveness, linear-scan register allocation and layout (stages separated by End markers).
void lower(const SsaProgram& prog, Expression::Impl& impl) {
  const std::vector<SsaInstr>& code = prog.code;
  const std::uint32_t num_values = prog.num_values;
  const int n = prog.n;
  // Last position each value is needed at. Outputs of stage s are read right after it, i.e.
  // they live until position stage_end[s] (the next stage's first instruction may reuse them).
  std::vector<std::size_t> last_use(num_values, 0);
  std::vector<bool> used_any(num_values, false);
  auto use = [&](std::uint32_t v, std::size_t pos) {
    used_any[v] = true;
    last_use[v] = std::max(last_use[v], pos);
  };
  for (std::size_t i = 0; i < code.size(); ++i) {
    int inputs = info(code[i].op).inputs;
    if (inputs >= 1) use(code[i].a, i);
    if (inputs >= 2) use(code[i].b, i);
    if (code[i].op == Op::Select) use(select_else(code[i].d), i);
  }
  if (!prog.value.is_const) use(prog.value.v, prog.stage_end[0]);
  for (const auto& [k, o] : prog.grad)
    if (!o.is_const) use(o.v, prog.stage_end[1]);
  for (const auto& [k, o] : prog.hess)
    if (!o.is_const) use(o.v, prog.stage_end[2]);

  std::vector<std::uint32_t> phys(num_values, 0);
  // Free registers, lowest first (keeps the register file compact and deterministic).
  std::priority_queue<std::uint32_t, std::vector<std::uint32_t>, std::greater<>> free_regs;
  std::uint32_t num_regs = 0;
  auto alloc = [&]() {
    if (free_regs.empty()) return num_regs++;
    std::uint32_t r = free_regs.top();
    free_regs.pop();
    return r;
  };
  std::vector<std::vector<std::uint32_t>> dying(code.size() + 1);
  for (std::uint32_t v = 0; v < num_values; ++v)
    if (used_any[v]) dying[std::min(last_use[v], code.size())].push_back(v);
  std::vector<Instr>& out = impl.code;
  out.clear();
  impl.slots.clear();
  for (const auto& [v, var] : prog.loads) {
    phys[v] = alloc();
    impl.slots.push_back({static_cast<std::uint32_t>(var), phys[v]});
  }
  if (!prog.loads.empty())
    out.push_back({Op::LoadX, 0, 0, static_cast<std::uint32_t>(impl.slots.size()), 0.0, 0.0});

  // Output entries: registers or constants (structural zeros included).
  auto outputs = [&](const std::vector<std::pair<int, Operand>>& entries, bool hessian,
                     std::vector<ConstSlot>& consts, std::vector<OutputSlot>& regs) {
    const std::size_t size = hessian ? static_cast<std::size_t>(n) * n : n;
    std::vector<double> cval(size, 0.0);
    std::vector<bool> is_reg(size, false);
    for (const auto& [idx, o] : entries) {
      int i = hessian ? idx / n : idx, j = hessian ? idx % n : 0;
      for (int k : {hessian ? i * n + j : i, j * n + i}) {
        if (o.is_const) {
          cval[k] = o.c;
        } else {
          is_reg[k] = true;
          regs.push_back({static_cast<std::uint32_t>(k), phys[o.v]});
        }
        if (!hessian || i == j) break;
      }
    }
    for (std::size_t k = 0; k < size; ++k)
      if (!is_reg[k]) consts.push_back({static_cast<std::uint32_t>(k), cval[k]});
  };
  // One output block: zero-fill when there are many zeros, then constants and registers.
  auto make_block = [&](const std::vector<ConstSlot>& consts, const std::vector<OutputSlot>& regs,
                        std::size_t size) {
    OutBlock bl;
    if (size <= kMaxDenseOutput) {
      std::vector<std::uint32_t> src(size, 0);
      for (const ConstSlot& c : consts) {
        auto it = std::find(impl.pool.begin(), impl.pool.end(), c.value);
        if (it == impl.pool.end()) it = impl.pool.insert(impl.pool.end(), c.value);
        src[c.index] = kConstSource | static_cast<std::uint32_t>(it - impl.pool.begin());
      }
      for (const OutputSlot& o : regs) src[o.index] = o.reg;
      bl.dense_n = static_cast<std::uint32_t>(size);
      bl.d_off = static_cast<std::uint32_t>(impl.sources.size());
      impl.sources.insert(impl.sources.end(), src.begin(), src.end());
      impl.blocks.push_back(bl);
      return static_cast<std::uint32_t>(impl.blocks.size() - 1);
    }
    std::size_t zeros = 0;
    for (const ConstSlot& c : consts) zeros += c.value == 0.0;
    bl.fill = zeros > 4 ? static_cast<std::uint32_t>(size) : 0;
    bl.c_off = static_cast<std::uint32_t>(impl.consts.size());
    for (const ConstSlot& c : consts)
      if (!bl.fill || c.value != 0.0) impl.consts.push_back(c);
    bl.c_n = static_cast<std::uint32_t>(impl.consts.size()) - bl.c_off;
    bl.r_off = static_cast<std::uint32_t>(impl.slots.size());
    impl.slots.insert(impl.slots.end(), regs.begin(), regs.end());
    bl.r_n = static_cast<std::uint32_t>(regs.size());
    impl.blocks.push_back(bl);
    return static_cast<std::uint32_t>(impl.blocks.size() - 1);
  };

  // Small dense outputs get an op of their own (unrolled, no block lookup).
  auto specialise_output = [&](Instr& ins, Op first, std::initializer_list<std::uint32_t> sizes) {
    const OutBlock& bl = impl.blocks[ins.a];
    int k = 0;
    for (std::uint32_t size : sizes) {
      if (bl.dense_n == size) {
        ins.op = static_cast<Op>(static_cast<int>(first) + k);
        ins.b = bl.d_off;
      }
      ++k;
    }
  };
  std::size_t stage = 0;
  auto close_stages = [&](std::size_t i) {
    while (stage < 3 && prog.stage_end[stage] == i) {
      // Registers are known once the stage's instructions are allocated.
      if (stage == 0) {
        if (prog.value.is_const)
          out.push_back({Op::ValueOutC, 0, 0, 0, prog.value.c, 0.0});
        else
          out.push_back({Op::ValueOut, 0, phys[prog.value.v], 0, 0.0, 0.0});
      } else if (stage == 1 && impl.order >= 1) {
        std::vector<OutputSlot> regs;
        outputs(prog.grad, false, impl.grad_const, regs);
        out.push_back({Op::GradOut, 0, make_block(impl.grad_const, regs, n), 0, 0.0, 0.0});
        specialise_output(out.back(), Op::GradOut1, {1, 2, 3, 4});
      } else if (stage == 2 && impl.order >= 2) {
        std::vector<OutputSlot> regs;
        outputs(prog.hess, true, impl.hess_const, regs);
        out.push_back({Op::HessOut, 0,
                       make_block(impl.hess_const, regs, static_cast<std::size_t>(n) * n), 0,
                       0.0, 0.0});
        specialise_output(out.back(), Op::HessOut1, {1, 4, 9, 16});
      }
      if (stage == 2) out.push_back({Op::End, 0, 0, 0, 0.0, 0.0});
      ++stage;
    }
  };
  for (std::size_t i = 0; i < code.size(); ++i) {
    close_stages(i);
    const SsaInstr& in = code[i];
    // Inputs dying here (and outputs of the previous stage, already stored) may be reused by
    // this instruction's outputs: the interpreter reads inputs before writing outputs.
    for (std::uint32_t v : dying[i]) free_regs.push(phys[v]);
    Instr ins{in.op, 0, 0, 0, in.c, in.d};
    int inputs = info(in.op).inputs;
    if (inputs >= 1) ins.a = phys[in.a];
    if (inputs >= 2) ins.b = phys[in.b];
    if (in.op == Op::Select) ins.d = select_else_bits(phys[select_else(in.d)]);
    phys[in.dst] = alloc();
    ins.dst = phys[in.dst];
    if (in.op == Op::SinCos) {
      phys[in.b] = alloc();
      ins.b = phys[in.b];
      if (!used_any[in.b]) free_regs.push(phys[in.b]);
    }
    if (!used_any[in.dst]) free_regs.push(phys[in.dst]);
    out.push_back(ins);
  }
  close_stages(code.size());
  impl.view = {impl.code.data(),   impl.slots.data(),   impl.consts.data(),
               impl.blocks.data(), impl.sources.data(), impl.pool.data()};
  impl.instructions = static_cast<int>(code.size());
  impl.registers = static_cast<int>(std::max<std::uint32_t>(num_regs, 1));
}

/// Turns on the quadratic kernel (impl.quad.A already holds the constant Hessian over the used
/// variables) after taking c0 and b from the tape at x = 0 and checking the kernel against the
/// tape at a few points.
void setup_quadratic(Expression::Impl& impl) {
  Quadratic& q = impl.quad;
  const int n = impl.n;
  const int m = static_cast<int>(impl.used.size());
  q.m = m;
  for (int k = 0; k < m; ++k) q.u[k] = static_cast<std::uint32_t>(impl.used[k]);
  q.identity = m == n;
  q.diagonal = true;
  for (int k = 0; k < m; ++k)
    for (int l = 0; l < m; ++l)
      if (k != l && q.A[k * m + l] != 0.0) q.diagonal = false;
  std::vector<double> x(n, 0.0), g(n), r(impl.registers), g2(n);
  double v = 0.0, v2 = 0.0;
  impl.run_tape_program(x.data(), r.data(), v, g.data(), nullptr);
  if (!std::isfinite(v)) return;
  q.c0 = v;
  for (int k = 0; k < m; ++k) {
    q.b[k] = g[q.u[k]];
    if (!std::isfinite(q.b[k])) return;
  }
  double scale = 1.0 + std::fabs(q.c0);
  for (int k = 0; k < m; ++k) scale += std::fabs(q.b[k]);
  for (double a : q.A) scale += std::fabs(a);
  q.active = true;
  const Expression::Kernel kernel = impl.select_kernel();
  q.active = false;
  std::uint64_t state = 0x9E3779B97F4A7C15ull;
  for (int trial = 0; trial < 3; ++trial) {
    for (double& xi : x) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      xi = -2.0 + 4.0 * static_cast<double>(state >> 11) * 0x1.0p-53;
    }
    impl.run_tape_program(x.data(), r.data(), v, g.data(), nullptr);
    kernel(impl, x.data(), v2, g2.data(), nullptr, nullptr);
    const double tol = 1e-9 * scale * 9.0;
    if (!(std::fabs(v - v2) <= tol)) return;
    for (int i = 0; i < n; ++i)
      if (!(std::fabs(g[i] - g2[i]) <= tol)) return;
  }
  q.active = true;
}

}  // namespace

std::mutex& ginac_mutex() {
  static std::mutex m;
  return m;
}

/// Budget of the compilation without CSE: this many nodes, at least kPlainBudgetMin.
constexpr std::size_t kPlainBudgetMin = 1 << 16;
constexpr std::size_t kPlainBudgetFactor = 16;

void compile_tape(const Symbolic& s, const std::vector<GiNaC::realsymbol>& syms,
                  Expression::Impl& impl) {
  const int n = impl.n;
  const int derivative_order = impl.order;
  const GiNaC::ex& value = s.value;
  const std::vector<ex>& grad = s.grad;
  const std::vector<ex>& hess = s.hess;
  // Compile: value, then gradient, then Hessian, one shared CSE context.
  SsaProgram prog, plain_prog;
  auto compile_all = [&](Compiler& comp, SsaProgram& out) {
    out.n = n;
    comp.scan(value);
    for (const ex& g : grad) comp.scan(g);
    if (derivative_order >= 2)
      for (const ex& h : hess) comp.scan(h);
    out.value = comp.compile(value);
    out.stage_end[0] = comp.size();
    if (derivative_order >= 1)
      for (int i : impl.used) out.grad.push_back({i, comp.compile(grad[i])});
    out.stage_end[1] = comp.size();
    if (derivative_order >= 2)
      for (int i : impl.used)
        for (int j : impl.used)
          if (j >= i) out.hess.push_back({i * n + j, comp.compile(hess[i * n + j])});
    out.stage_end[2] = comp.size();
    out.code = comp.code();
    out.loads = comp.loads();
    out.num_values = comp.num_values();
  };
  Compiler comp(syms, true);
  compile_all(comp, prog);
  // The same targets without CSE, for diagnostics (tape_size_without_cse), within a budget.
  const std::size_t budget = std::max<std::size_t>(kPlainBudgetMin, kPlainBudgetFactor * comp.size());
  bool plain_complete = true;
  try {
    Compiler plain(syms, false, budget);
    compile_all(plain, plain_prog);
  } catch (const Compiler::OverBudget&) {
    plain_complete = false;
  }

  if (s.hessian_constant) {
    const int m = static_cast<int>(impl.used.size());
    for (int k = 0; k < m; ++k)
      for (int l = 0; l < m; ++l)
        impl.quad.A[k * m + l] = constant_value(hess[impl.used[k] * n + impl.used[l]]);
  }

  if (plain_complete) {
    fuse(plain_prog);
    impl.tape_without_cse = static_cast<int>(plain_prog.code.size());
  } else {
    impl.tape_without_cse = static_cast<int>(std::min<std::size_t>(budget, INT32_MAX));
  }
  fuse(prog);
  lower(prog, impl);
  if (s.hessian_constant) setup_quadratic(impl);
}

}  // namespace expr_detail
}  // namespace refdyn
