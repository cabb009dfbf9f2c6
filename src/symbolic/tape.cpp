// The generated C as a graph of double operations (see tape.hpp).
#include "tape.hpp"

#include "printer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>

namespace refdyn::symbolic_detail {

Tape*& current_tape() {
  static thread_local Tape* tape = nullptr;
  return tape;
}

// ---- the Tape --------------------------------------------------------------------------------

int Tape::intern(Node n) {
  std::uint64_t bits = 0;
  std::memcpy(&bits, &n.value, sizeof bits);
  auto k = std::make_tuple(static_cast<int>(n.op), n.args, bits, n.text);
  const auto it = index_.find(k);
  if (it != index_.end()) return it->second;
  const int id = static_cast<int>(nodes_.size());
  nodes_.push_back(std::move(n));
  index_.emplace(std::move(k), id);
  return id;
}

int Tape::constant(double v) {
  Node n;
  n.op = Op::Const;
  n.value = v == 0 ? 0.0 : v;  // one zero
  return intern(std::move(n));
}

int Tape::leaf(const std::string& text) {
  Node n;
  n.op = Op::Leaf;
  n.text = text;
  return intern(std::move(n));
}

namespace {
Tape::Node binary(Tape::Op op, int a, int b) {
  Tape::Node n;
  n.op = op;
  n.args = {a, b};
  return n;
}
}  // namespace

int Tape::add(int a, int b) {
  if (is_const(a, 0)) return b;
  if (is_const(b, 0)) return a;
  if (node(a).op == Op::Const && node(b).op == Op::Const) return constant(node(a).value + node(b).value);
  if (node(b).op == Op::Neg) return sub(a, node(b).args[0]);
  if (node(a).op == Op::Neg) return sub(b, node(a).args[0]);
  if (a == b) return mul(constant(2.0), a);
  // constants gathered: (x + c1) + c2 → x + (c1 + c2)
  if (node(a).op == Op::Const) std::swap(a, b);
  if (node(b).op == Op::Const && node(a).op == Op::Add) {
    // Operands copied, not referenced: constant() may grow nodes_ and move every Node.
    const int s0 = node(a).args[0], s1 = node(a).args[1];
    const double cb = node(b).value;
    if (node(s0).op == Op::Const) {
      const int c = constant(node(s0).value + cb);
      return add(s1, c);
    }
    if (node(s1).op == Op::Const) {
      const int c = constant(node(s1).value + cb);
      return add(s0, c);
    }
  }
  if (a > b) std::swap(a, b);
  return intern(binary(Op::Add, a, b));
}

int Tape::sub(int a, int b) {
  if (is_const(b, 0)) return a;
  if (is_const(a, 0)) return neg(b);
  if (a == b) return constant(0.0);
  if (node(a).op == Op::Const && node(b).op == Op::Const) return constant(node(a).value - node(b).value);
  if (node(b).op == Op::Neg) return add(a, node(b).args[0]);
  if (node(b).op == Op::Const) return add(a, constant(-node(b).value));
  if (node(a).op == Op::Neg) return neg(add(node(a).args[0], b));
  return intern(binary(Op::Sub, a, b));
}

int Tape::mul(int a, int b) {
  if (is_const(a, 0) || is_const(b, 0)) return constant(0.0);
  if (is_const(a, 1)) return b;
  if (is_const(b, 1)) return a;
  if (is_const(a, -1)) return neg(b);
  if (is_const(b, -1)) return neg(a);
  if (node(a).op == Op::Const && node(b).op == Op::Const) return constant(node(a).value * node(b).value);
  if (node(a).op == Op::Neg) return neg(mul(node(a).args[0], b));
  if (node(b).op == Op::Neg) return neg(mul(a, node(b).args[0]));
  if (node(a).op == Op::Const && node(a).value < 0) return neg(mul(constant(-node(a).value), b));
  if (node(b).op == Op::Const && node(b).value < 0) return neg(mul(a, constant(-node(b).value)));
  // constants gathered: c1·(c2·x) → (c1·c2)·x
  if (node(b).op == Op::Const) std::swap(a, b);
  if (node(a).op == Op::Const && node(b).op == Op::Mul && node(node(b).args[0]).op == Op::Const)
    return mul(constant(node(a).value * node(node(b).args[0]).value), node(b).args[1]);
  // constants first (c*x), then by node order
  const bool ca = node(a).op == Op::Const, cb = node(b).op == Op::Const;
  if (cb && !ca) std::swap(a, b);
  else if (ca == cb && a > b) std::swap(a, b);
  return intern(binary(Op::Mul, a, b));
}

int Tape::div(int a, int b) {
  if (is_const(a, 0)) return constant(0.0);
  if (is_const(b, 1)) return a;
  if (node(a).op == Op::Const && node(b).op == Op::Const) return constant(node(a).value / node(b).value);
  if (node(a).op == Op::Neg) return neg(div(node(a).args[0], b));
  if (node(b).op == Op::Neg) return neg(div(a, node(b).args[0]));
  return intern(binary(Op::Div, a, b));
}

int Tape::neg(int a) {
  if (node(a).op == Op::Const) return constant(-node(a).value);
  if (node(a).op == Op::Neg) return node(a).args[0];
  if (node(a).op == Op::Sub) return sub(node(a).args[1], node(a).args[0]);
  Node n;
  n.op = Op::Neg;
  n.args = {a};
  return intern(std::move(n));
}

int Tape::pow(int a, long p) {
  if (node(a).op == Op::Const) return constant(std::pow(node(a).value, static_cast<double>(p)));
  Node n;
  n.op = Op::Pow;
  n.value = static_cast<double>(p);
  n.args = {a};
  return intern(std::move(n));
}

int Tape::call(const std::string& name, std::vector<int> args) {
  if (args.size() == 1 && node(args[0]).op == Op::Const) {
    const double v = node(args[0]).value;
    static const std::map<std::string, double (*)(double)> f = {
        {"sin", [](double x) { return std::sin(x); }},   {"cos", [](double x) { return std::cos(x); }},
        {"tan", [](double x) { return std::tan(x); }},   {"exp", [](double x) { return std::exp(x); }},
        {"sqrt", [](double x) { return std::sqrt(x); }}, {"fabs", [](double x) { return std::fabs(x); }}};
    const auto it = f.find(name);
    if (it != f.end() && std::isfinite(it->second(v))) return constant(it->second(v));
  }
  Node n;
  n.op = Op::Call;
  n.text = name;
  n.args = std::move(args);
  return intern(std::move(n));
}

int Tape::cond(bool strict, int a, int b, int c, int d) {
  Node n;
  n.op = Op::Cond;
  n.value = strict ? 1 : 0;
  n.args = {a, b, c, d};
  return intern(std::move(n));
}

// ---- GiNaC onto the Tape ---------------------------------------------------------------------

namespace {
std::uint64_t fnv(std::uint64_t h, const std::string& s) {
  for (unsigned char ch : s) {
    h ^= ch;
    h *= 1099511628211ull;
  }
  return h;
}
std::uint64_t fnv(std::uint64_t h, std::uint64_t v) {
  for (int k = 0; k < 8; ++k) {
    h ^= (v >> (8 * k)) & 0xff;
    h *= 1099511628211ull;
  }
  return h;
}
constexpr std::uint64_t kSeed = 14695981039346656037ull;

std::string numeric_text(const GiNaC::numeric& x) {
  if (x.is_rational()) {
    std::ostringstream o;
    o << "r" << x.numer() << "/" << x.denom();
    return o.str();
  }
  return "f" + double_text(x.to_double(), 17);
}
}  // namespace

namespace {
std::string coef_text(const GiNaC::numeric& x) { return numeric_text(x); }
const std::uint64_t kNumberKey = fnv(kSeed, "1");  // the key of every number (its ê is 1)
std::uint64_t tag(std::uint64_t h, const GiNaC::numeric& c) { return fnv(h, coef_text(c)); }
}  // namespace

const Canon::View& Canon::operator()(const ex& e) {
  const auto hit = memo_.find(e);
  if (hit != memo_.end()) return hit->second;
  View r;
  std::uint64_t h = kSeed;
  if (is_a<GiNaC::symbol>(e)) {
    h = fnv(h, "s" + GiNaC::ex_to<GiNaC::symbol>(e).get_name());
  } else if (is_a<GiNaC::numeric>(e)) {
    r.coef = GiNaC::ex_to<GiNaC::numeric>(e);
    h = kNumberKey;
  } else if (is_a<GiNaC::constant>(e)) {
    h = fnv(h, "c" + double_text(GiNaC::ex_to<GiNaC::numeric>(e.evalf()).to_double(), 17));
  } else if (is_a<GiNaC::add>(e)) {
    std::vector<std::pair<std::uint64_t, GiNaC::numeric>> ts;
    for (size_t i = 0; i < e.nops(); ++i) {
      const View& t = (*this)(e.op(i));
      ts.emplace_back(t.key, t.coef);
    }
    std::stable_sort(ts.begin(), ts.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    // normalized by the first term that is not a number (a sum has one)
    r.coef = ts[0].second;
    for (size_t i = 0; i < e.nops(); ++i)
      if (ts[i].first != kNumberKey) {
        r.coef = ts[i].second;
        break;
      }
    h = fnv(h, "+");
    for (const auto& [k, c] : ts) h = tag(fnv(h, k), c / r.coef);
  } else if (is_a<GiNaC::mul>(e)) {
    std::vector<std::uint64_t> ks;
    for (size_t i = 0; i < e.nops(); ++i) {
      const View& f = (*this)(e.op(i));
      r.coef *= f.coef;
      if (!is_a<GiNaC::numeric>(e.op(i))) ks.push_back(f.key);
    }
    std::sort(ks.begin(), ks.end());
    if (ks.size() == 1) {
      h = ks[0];
    } else {
      h = fnv(h, "*");
      for (std::uint64_t k : ks) h = fnv(h, k);
    }
  } else if (is_a<GiNaC::power>(e)) {
    const View b = (*this)(e.op(0));
    if (is_a<GiNaC::numeric>(e.op(1)) && GiNaC::ex_to<GiNaC::numeric>(e.op(1)).is_integer()) {
      const GiNaC::numeric p = GiNaC::ex_to<GiNaC::numeric>(e.op(1));
      r.coef = b.coef.power(p);
      h = tag(fnv(fnv(h, "^"), b.key), p);
    } else {
      const View p = (*this)(e.op(1));
      h = tag(fnv(tag(fnv(fnv(h, "^r"), b.key), b.coef), p.key), p.coef);
    }
  } else if (is_a<GiNaC::function>(e)) {
    h = fnv(h, "f" + GiNaC::ex_to<GiNaC::function>(e).get_name());
    for (size_t i = 0; i < e.nops(); ++i) {
      const View a = (*this)(e.op(i));
      h = tag(fnv(h, a.key), a.coef);
    }
  } else {
    h = fnv(h, "?" + expr_detail::to_text(e));
  }
  r.key = h;
  return memo_.emplace(e, r).first->second;
}

std::vector<std::pair<GiNaC::numeric, ex>> Canon::terms(const ex& sum) {
  std::vector<std::tuple<std::uint64_t, GiNaC::numeric, ex>> v;
  for (size_t i = 0; i < sum.nops(); ++i) {
    const View& t = (*this)(sum.op(i));
    v.emplace_back(t.key, t.coef, sum.op(i));
  }
  std::stable_sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });
  const GiNaC::numeric lead = (*this)(sum).coef;
  std::vector<std::pair<GiNaC::numeric, ex>> out;
  for (auto& [k, c, t] : v) out.emplace_back(c / lead, t);
  return out;
}

std::vector<ex> Canon::factors(const ex& product) {
  std::vector<std::pair<std::uint64_t, ex>> v;
  for (size_t i = 0; i < product.nops(); ++i)
    if (!is_a<GiNaC::numeric>(product.op(i))) v.emplace_back((*this)(product.op(i)).key, product.op(i));
  std::stable_sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<ex> out;
  for (auto& [k, f] : v) out.push_back(f);
  return out;
}

int FromGinac::operator()(const ex& e) {
  if (!is_a<GiNaC::add>(e)) return scaled(canon_(e).coef, norm(e));
  // a sum whole: its terms with their own coefficients (c·rᵢ, exact), in key order
  const auto hit = whole_.find(e);
  if (hit != whole_.end()) return hit->second;
  const GiNaC::numeric c = canon_(e).coef;
  int id = -1;
  for (const auto& [r, t] : canon_.terms(e)) {
    const GiNaC::numeric ci = c * r;
    const int v = scaled(GiNaC::abs(ci), norm(t));
    id = id < 0 ? (ci.is_negative() ? tape_.neg(v) : v) : ci.is_negative() ? tape_.sub(id, v) : tape_.add(id, v);
  }
  whole_.emplace(e, id);
  return id;
}

int FromGinac::scaled(const GiNaC::numeric& c0, int v) {
  if (c0.is_equal(1)) return v;
  const bool negative = c0.is_negative();
  const GiNaC::numeric c = GiNaC::abs(c0);
  int r = v;
  if (c.is_rational() && !c.is_integer() && c.numer() < 100000 && c.denom() < 100000) {
    if (!c.numer().is_equal(1)) r = tape_.mul(tape_.constant(c.numer().to_double()), r);
    r = tape_.div(r, tape_.constant(c.denom().to_double()));
  } else if (!c.is_equal(1)) {
    r = tape_.mul(tape_.constant(c.to_double()), r);
  }
  return negative ? tape_.neg(r) : r;
}

int FromGinac::power(int base, long p) {
  if (keep_powers_ && p >= 2) return tape_.pow(base, p);
  if (p <= 4) {
    int r = base;
    for (long k = 1; k < p; ++k) r = tape_.mul(r, base);
    return r;
  }
  return tape_.call("pow", {base, tape_.constant(static_cast<double>(p))});
}

int FromGinac::norm(const ex& e) {
  const std::uint64_t key = canon_(e).key;
  if (is_a<GiNaC::numeric>(e)) return tape_.constant(1.0);
  const auto hit = memo_.find(key);
  if (hit != memo_.end()) return hit->second;
  int id = -1;
  if (is_a<GiNaC::symbol>(e)) {
    id = tape_.leaf(leaf_(GiNaC::ex_to<GiNaC::symbol>(e)));
  } else if (is_a<GiNaC::constant>(e)) {
    id = keep_powers_ ? tape_.leaf("pi") : tape_.constant(GiNaC::ex_to<GiNaC::numeric>(e.evalf()).to_double());
  } else if (is_a<GiNaC::add>(e)) {
    for (const auto& [r, t] : canon_.terms(e)) {
      const int v = scaled(GiNaC::abs(r), norm(t));
      id = id < 0 ? (r.is_negative() ? tape_.neg(v) : v) : r.is_negative() ? tape_.sub(id, v) : tape_.add(id, v);
    }
  } else if (is_a<GiNaC::mul>(e)) {
    int num = -1, den = -1;
    auto times = [&](int& acc, int v) { acc = acc < 0 ? v : tape_.mul(acc, v); };
    for (const ex& f : canon_.factors(e)) {
      if (is_a<GiNaC::power>(f) && is_a<GiNaC::numeric>(f.op(1)) && GiNaC::ex_to<GiNaC::numeric>(f.op(1)).is_integer() &&
          GiNaC::ex_to<GiNaC::numeric>(f.op(1)).is_negative()) {
        times(den, power(norm(f.op(0)), -GiNaC::ex_to<GiNaC::numeric>(f.op(1)).to_long()));
        continue;
      }
      times(num, norm(f));
    }
    if (num < 0) num = tape_.constant(1.0);
    id = den < 0 ? num : tape_.div(num, den);
  } else if (is_a<GiNaC::power>(e)) {
    if (is_a<GiNaC::numeric>(e.op(1)) && GiNaC::ex_to<GiNaC::numeric>(e.op(1)).is_integer()) {
      const long p = GiNaC::ex_to<GiNaC::numeric>(e.op(1)).to_long();
      const int b = norm(e.op(0));
      id = p < 0 ? tape_.div(tape_.constant(1.0), power(b, -p)) : power(b, p);
    } else {
      const int b = (*this)(e.op(0));
      const ex p = e.op(1);
      if (p.is_equal(GiNaC::numeric(1, 2))) id = tape_.call("sqrt", {b});
      else if (p.is_equal(GiNaC::numeric(-1, 2))) id = tape_.div(tape_.constant(1.0), tape_.call("sqrt", {b}));
      else id = tape_.call("pow", {b, (*this)(p)});
    }
  } else if (is_a<GiNaC::function>(e)) {
    const unsigned s = GiNaC::ex_to<GiNaC::function>(e).get_serial();
    std::vector<int> a;
    for (size_t i = 0; i < e.nops(); ++i) a.push_back((*this)(e.op(i)));
    using namespace expr_detail;
    const std::pair<unsigned, const char*> piecewise[] = {{serial_abs(), "fabs"},     {serial_sgn(), "rd_sgn"},
                                                          {serial_min(), "rd_min"},   {serial_max(), "rd_max"},
                                                          {serial_step(), "rd_step"}, {serial_clamp(), "rd_clamp"}};
    if (s == serial_constant()) {
      id = a[0];  // a model constant: the number
    } else if (s == serial_if_lt() || s == serial_if_le()) {
      id = tape_.cond(s == serial_if_lt(), a[0], a[1], a[2], a[3]);
    } else {
      const std::string name = GiNaC::ex_to<GiNaC::function>(e).get_name();
      std::string cname = name == "abs" ? "fabs" : name;
      for (const auto& [serial, pname] : piecewise)
        if (s == serial) cname = pname;
      id = tape_.call(cname, a);
    }
  } else {
    throw Error("generate: cannot write the expression " + expr_detail::to_text(e));
  }
  memo_.emplace(key, id);
  return id;
}

// ---- C text ----------------------------------------------------------------------------------

namespace {
class Emitter {
 public:
  Emitter(const Tape& t, bool cse) : t_(t), cse_(cse), uses_(t.size(), 0), name_(t.size()) {}
  void count(int id) {
    if (uses_[id]++ > 0) return;
    for (int a : t_.node(id).args) count(a);
  }
  bool temporary(int id) const {
    const auto op = t_.node(id).op;
    return cse_ && uses_[id] >= 2 && op != Tape::Op::Const && op != Tape::Op::Leaf;
  }
  /// The text of a node (its temporary's name, or the operation with its operands inlined).
  std::string text(int id) {
    if (!name_[id].empty()) return name_[id];
    const Tape::Node& n = t_.node(id);
    switch (n.op) {
      case Tape::Op::Const: {
        std::string s = double_text(std::fabs(n.value), 17);
        if (n.value == std::trunc(n.value) && std::fabs(n.value) < 4503599627370496.0) s += ".0";
        return n.value < 0 ? "(-" + s + ")" : s;
      }
      case Tape::Op::Leaf: return n.text;
      case Tape::Op::Add: {
        ++operations;
        int a = n.args[0], b = n.args[1];
        if (t_.node(a).op == Tape::Op::Const) std::swap(a, b);
        if (t_.node(b).op == Tape::Op::Const && t_.node(b).value < 0)
          return text(a) + " - " + double_text(-t_.node(b).value, 17) +
                 (-t_.node(b).value == std::trunc(t_.node(b).value) && std::fabs(t_.node(b).value) < 4503599627370496.0 ? ".0" : "");
        return text(a) + " + " + text(b);
      }
      case Tape::Op::Sub: ++operations; return text(n.args[0]) + " - " + operand(n.args[1], 1);
      case Tape::Op::Mul: ++operations; return operand(n.args[0], 2) + "*" + operand(n.args[1], 2);
      case Tape::Op::Div: ++operations; return operand(n.args[0], 2) + "/" + operand(n.args[1], 3);
      case Tape::Op::Neg: return "-" + operand(n.args[0], 2);
      case Tape::Op::Call: {
        ++operations;
        std::string s = n.text + "(";
        for (size_t i = 0; i < n.args.size(); ++i) s += (i ? ", " : "") + text(n.args[i]);
        return s + ")";
      }
      case Tape::Op::Pow: ++operations; return "pow(" + text(n.args[0]) + ", " + double_text(n.value, 17) + ".0)";
      case Tape::Op::Cond:
        return "(" + text(n.args[0]) + (n.value != 0 ? " < " : " <= ") + text(n.args[1]) + " ? " + text(n.args[2]) +
               " : " + text(n.args[3]) + ")";
    }
    return "";
  }
  /// An operand of an operation of the given level (1: right of −, 2: factor, 3: divisor),
  /// parenthesised where C's precedence needs it.
  std::string operand(int id, int level) {
    const std::string s = text(id);
    if (!name_[id].empty()) return s;
    const auto op = t_.node(id).op;
    const bool low = op == Tape::Op::Add || op == Tape::Op::Sub || (level >= 2 && op == Tape::Op::Neg) ||
                     (level == 3 && (op == Tape::Op::Mul || op == Tape::Op::Div));
    return low ? "(" + s + ")" : s;
  }
  std::string define(int id, const std::string& indent, long& temporaries) {
    const std::string s = text(id);
    name_[id] = "t" + std::to_string(temporaries++);
    return indent + "const double " + name_[id] + " = " + s + ";\n";
  }
  long operations = 0;

 private:
  const Tape& t_;
  bool cse_;
  std::vector<int> uses_;
  std::vector<std::string> name_;
};
}  // namespace

std::string emit(const Tape& tape, const std::vector<std::pair<std::string, int>>& outputs, bool cse,
                 const std::string& indent, long& temporaries, long& operations) {
  Emitter em(tape, cse);
  for (const auto& [lhs, id] : outputs) em.count(id);
  std::string code;
  long temps = 0;
  // temporaries in Tape order (operands before their uses), each just before the first output
  // that needs it
  std::vector<char> done(tape.size(), 0);
  std::function<void(int)> define = [&](int id) {
    if (done[id]) return;
    done[id] = 1;
    for (int a : tape.node(id).args) define(a);
    if (em.temporary(id)) code += em.define(id, indent, temps);
  };
  for (const auto& [lhs, id] : outputs) {
    define(id);
    code += indent + lhs + " = " + em.text(id) + ";\n";
  }
  temporaries += temps;
  operations += em.operations;
  return code;
}

namespace {
/// The expression language's text of node n, its operands written by sub(operand, level); level
/// as in the C emitter (0 any, 1 right of −, 2 factor, 3 divisor, 4 base of a power).
template <class Sub>
std::string op_text(const Tape& t, const Tape::Node& n, Sub&& sub) {
  switch (n.op) {
    case Tape::Op::Const: {
      std::string s = double_text(std::fabs(n.value), 17);
      return n.value < 0 ? "-" + s : s;
    }
    case Tape::Op::Leaf: return n.text;
    case Tape::Op::Add: {
      int a = n.args[0], b = n.args[1];
      if (t.node(a).op == Tape::Op::Const) std::swap(a, b);
      if (t.node(b).op == Tape::Op::Const && t.node(b).value < 0) return sub(a, 0) + " - " + double_text(-t.node(b).value, 17);
      return sub(a, 0) + " + " + sub(b, 0);
    }
    case Tape::Op::Sub: return sub(n.args[0], 0) + " - " + sub(n.args[1], 1);
    case Tape::Op::Mul: return sub(n.args[0], 2) + "*" + sub(n.args[1], 2);
    case Tape::Op::Div: return sub(n.args[0], 2) + "/" + sub(n.args[1], 3);
    case Tape::Op::Neg: return "-" + sub(n.args[0], 2);
    case Tape::Op::Pow: return sub(n.args[0], 4) + "^" + double_text(n.value, 17);
    case Tape::Op::Call: {
      static const std::map<std::string, std::string> names = {
          {"fabs", "abs"}, {"rd_min", "min"}, {"rd_max", "max"}, {"rd_step", "step"}, {"rd_clamp", "clamp"}};
      if (n.text == "rd_sgn") return "if(" + sub(n.args[0], 0) + " >= 0, 1, -1)";
      if (n.text == "pow") return sub(n.args[0], 4) + "^" + sub(n.args[1], 4);
      const auto nm = names.find(n.text);
      std::string s = (nm == names.end() ? n.text : nm->second) + "(";
      for (size_t i = 0; i < n.args.size(); ++i) s += (i ? ", " : "") + sub(n.args[i], 0);
      return s + ")";
    }
    case Tape::Op::Cond:
      return "if(" + sub(n.args[0], 0) + (n.value != 0 ? " < " : " <= ") + sub(n.args[1], 0) + ", " + sub(n.args[2], 0) +
             ", " + sub(n.args[3], 0) + ")";
  }
  return "";
}

/// Whether node n's text needs parentheses as an operand of the given level.
bool low_at(const Tape::Node& n, int level) {
  const auto op = n.op;
  if (op == Tape::Op::Add || op == Tape::Op::Sub) return level >= 1;
  if (op == Tape::Op::Neg || (op == Tape::Op::Const && n.value < 0)) return level >= 1;
  if (op == Tape::Op::Mul || op == Tape::Op::Div) return level >= 3;
  if (op == Tape::Op::Pow || (op == Tape::Op::Call && n.text == "pow")) return level >= 4;
  return false;
}

std::string text_of(const Tape& t, int id, int level, std::map<int, std::string>& memo) {
  const Tape::Node& n = t.node(id);
  std::string s;
  const auto it = memo.find(id);
  if (it != memo.end()) {
    s = it->second;
  } else {
    s = op_text(t, n, [&](int a, int l) { return text_of(t, a, l, memo); });
    if (s.size() < 4096) memo.emplace(id, s);
  }
  return low_at(n, level) ? "(" + s + ")" : s;
}
}  // namespace

AuxiliaryTexts::AuxiliaryTexts(const Tape& tape, const std::vector<int>& roots, std::size_t shared, std::size_t single)
    : t_(tape), shared_(shared), single_(single), uses_(tape.size(), 0), name_(tape.size()) {
  // uses: the operand edges of the graph reachable from the roots (each node's operands once),
  // and one per root
  std::vector<char> seen(tape.size(), 0);
  std::vector<int> stack;
  for (int r : roots) {
    ++uses_[r];
    stack.push_back(r);
  }
  while (!stack.empty()) {
    const int id = stack.back();
    stack.pop_back();
    if (seen[id]) continue;
    seen[id] = 1;
    for (int a : t_.node(id).args) {
      ++uses_[a];
      if (!seen[a]) stack.push_back(a);
    }
  }
}

std::string AuxiliaryTexts::body(int id) {
  const auto it = memo_.find(id);
  if (it != memo_.end()) return it->second;
  std::string s = op_text(t_, t_.node(id), [&](int a, int l) { return ref(a, l); });
  memo_.emplace(id, s);
  return s;
}

std::string AuxiliaryTexts::ref(int id, int level) {
  if (!name_[id].empty()) return name_[id];
  const Tape::Node& n = t_.node(id);
  std::string s = body(id);
  if (n.op != Tape::Op::Const && n.op != Tape::Op::Leaf &&
      ((uses_[id] >= 2 && s.size() >= shared_) || s.size() >= single_)) {
    aux_.push_back(std::move(s));
    name_[id] = "aux(" + std::to_string(aux_.size()) + ")";
    memo_.erase(id);
    return name_[id];
  }
  if (uses_[id] < 2) memo_.erase(id);  // used once: not asked for again
  return low_at(n, level) ? "(" + s + ")" : s;
}

std::string AuxiliaryTexts::operator()(int id) {
  if (!name_[id].empty()) return name_[id];
  return body(id);
}

std::string expression_text(const Tape& tape, int id) {
  std::map<int, std::string> memo;
  return text_of(tape, id, 0, memo);
}

}  // namespace refdyn::symbolic_detail
