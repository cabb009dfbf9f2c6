// Expression engine, stage 3: the tape compiler. GiNaC expressions -> SSA with CSE and
// constant folding (here) -> peephole fusion -> liveness and register allocation -> the program
// the interpreter runs; set-up of the closed-form quadratic kernel (tape_backend.cpp).
#include "ssa.hpp"

#include "refdyn/common/text.hpp"

#include <algorithm>
#include <bit>
#include <set>
#include <tuple>
#include <unordered_map>
#include <unordered_set>

namespace refdyn {
namespace expr_detail {

using GiNaC::ex;

namespace {

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

  /// A structural key of e that is the same in every run: GiNaC orders the operands of sums and
  /// products by hashes seeded with addresses, so its order changes between runs, and a tape
  /// that summed in that order rounded differently from run to run (examples/mixed_orders'
  /// plan.csv differed in the last bits). The key mixes names, numbers and the operands' keys,
  /// sorted for sums and products; compile_add and compile_mul take their operands in key order.
  std::uint64_t structural_key(const ex& e) {
    const GiNaC::basic* p = &GiNaC::ex_to<GiNaC::basic>(e);
    auto it = skey_.find(p);
    if (it != skey_.end()) return it->second;
    auto mix = [](std::uint64_t h, std::uint64_t v) {
      return h ^ (v + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2));
    };
    auto text = [](const std::string& t) {  // FNV-1a
      std::uint64_t h = 0xcbf29ce484222325ULL;
      for (unsigned char ch : t) h = (h ^ ch) * 0x100000001b3ULL;
      return h;
    };
    std::uint64_t h;
    if (GiNaC::is_a<GiNaC::symbol>(e)) {
      h = mix(1, text(GiNaC::ex_to<GiNaC::symbol>(e).get_name()));
    } else if (GiNaC::is_a<GiNaC::numeric>(e)) {
      const GiNaC::numeric& n = GiNaC::ex_to<GiNaC::numeric>(e);
      h = mix(mix(2, std::bit_cast<std::uint64_t>(GiNaC::real(n).to_double())),
              std::bit_cast<std::uint64_t>(GiNaC::imag(n).to_double()));
    } else if (GiNaC::is_a<GiNaC::add>(e) || GiNaC::is_a<GiNaC::mul>(e)) {
      std::vector<std::uint64_t> keys;
      for (std::size_t i = 0; i < e.nops(); ++i) keys.push_back(structural_key(e.op(i)));
      std::sort(keys.begin(), keys.end());
      h = GiNaC::is_a<GiNaC::add>(e) ? 3 : 4;
      for (std::uint64_t k : keys) h = mix(h, k);
    } else {  // functions (by name), powers, constants (pi, e: by their text): operands in order
      h = mix(5, text(GiNaC::is_a<GiNaC::function>(e) ? GiNaC::ex_to<GiNaC::function>(e).get_name()
                      : e.nops() == 0                 ? to_text(e)
                                                      : std::string(GiNaC::ex_to<GiNaC::basic>(e).class_name())));
      for (std::size_t i = 0; i < e.nops(); ++i) h = mix(h, structural_key(e.op(i)));
    }
    skey_.emplace(key(e), h);
    return h;
  }

  /// The operands of a sum or product in structural_key order.
  std::vector<ex> operands_in_key_order(const ex& e) {
    std::vector<std::pair<std::uint64_t, ex>> ops;
    for (std::size_t i = 0; i < e.nops(); ++i) ops.emplace_back(structural_key(e.op(i)), e.op(i));
    std::stable_sort(ops.begin(), ops.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::vector<ex> out;
    for (auto& [k, o] : ops) out.push_back(std::move(o));
    return out;
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
      for (const ex& f : operands_in_key_order(e)) {
        if (has_sym(f))
          rest *= f;
        else
          constant *= f;
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
    for (const ex& term : operands_in_key_order(e)) {
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
    for (const ex& f : operands_in_key_order(e)) {
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
  std::unordered_map<const GiNaC::basic*, std::uint64_t> skey_;
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
