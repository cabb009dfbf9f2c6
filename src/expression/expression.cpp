// Expression engine, public API: construction (front end -> lowering -> tape compiler) and the
// accessors, evaluation entry points and diagnostics of refdyn::Expression.
#include "internal.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"

#include <algorithm>
#include <sstream>

namespace refdyn {

using namespace expr_detail;

GiNaC::ex expr_detail::symbolic_value(const std::string& text, const std::vector<std::string>& variables,
                                      const std::vector<GiNaC::realsymbol>& syms) {
  ExpressionOptions o;
  o.derivative_order = 0;
  o.specialize = false;
  const ParseResult fe = parse_front_end(text, variables, {}, o);
  return lower_symbolic(text, fe, syms, o).value;
}

Expression::Expression(const std::string& text, const std::vector<std::string>& variables,
                       const std::map<std::string, double>& parameters, int derivative_order)
    : Expression(text, variables, parameters, [&] {
        ExpressionOptions o;
        o.derivative_order = derivative_order;
        return o;
      }()) {}

Expression::Expression(const std::string& text, const std::vector<std::string>& variables,
                       const std::map<std::string, double>& parameters,
                       const ExpressionOptions& options) {
  const int derivative_order = options.derivative_order;
  auto impl = std::make_shared<Impl>();
  impl->source = text;
  if (derivative_order < 0 || derivative_order > 2)
    throw Error(expected_got("Expression derivative_order", "0, 1 or 2",
                             std::to_string(derivative_order)));
  impl->order = derivative_order;
  if (options.extra_derivative_order < 0)
    throw Error(expected_got("Expression extra_derivative_order", ">= 0", std::to_string(options.extra_derivative_order)));
  if (options.extra_derivative_order > 0 &&
      (options.extra_derivative_variable < 0 || options.extra_derivative_variable >= static_cast<int>(variables.size())))
    throw Error(expected_got("Expression extra_derivative_variable",
                             variables.empty() ? std::string("a variable's index (there are none)")
                                               : "0.." + std::to_string(variables.size() - 1),
                             std::to_string(options.extra_derivative_variable)));

  // Variable names: stripped, well-formed, unique, not parameters.
  for (const std::string& raw : variables) {
    std::string name = strip_spaces(raw);
    std::size_t i = 0;
    bool ok = !name.empty() && is_ident_start(name[0]);
    while (ok && i < name.size() && is_ident_char(name[i])) ++i;
    if (ok && i < name.size()) {
      // name(arg...) with balanced parentheses closing at the end.
      int depth = 0;
      ok = name[i] == '(' && name.back() == ')';
      for (std::size_t j = i; ok && j < name.size(); ++j) {
        if (name[j] == '(') ++depth;
        if (name[j] == ')' && --depth == 0 && j + 1 != name.size()) ok = false;
        if (depth < 0) ok = false;
      }
      ok = ok && depth == 0 && name.size() > i + 2;
    }
    if (!ok)
      throw Error(expected_got("Expression variable name", "an identifier or name(arg)",
                               "'" + raw + "'", "e.g. t, x(E), q(psi1)"));
    if (std::find(impl->variables.begin(), impl->variables.end(), name) != impl->variables.end())
      throw Error("Expression variables: '" + name +
                  "' is listed twice (hint: each variable must appear once in the argument list)");
    if (parameters.count(name))
      throw Error("Expression variables: '" + name +
                  "' is both a variable and a parameter (hint: remove it from one of the two)");
    impl->variables.push_back(name);
  }
  const int n = static_cast<int>(impl->variables.size());
  impl->n = n;

  std::lock_guard<std::mutex> lock(ginac_mutex());
  std::vector<GiNaC::realsymbol> syms;
  for (const auto& name : impl->variables) syms.emplace_back(name);
  ParseResult fe = parse_front_end(text, impl->variables, parameters, options);
  Symbolic s = lower_symbolic(text, fe, syms, options);
  impl->used = s.used;
  {
    std::vector<bool> seen(n, false);
    for (const AstNode& node : fe.nodes)
      if (node.kind == AstKind::Variable) seen[node.index] = true;
    for (int i = 0; i < n; ++i)
      if (seen[i]) impl->referenced.push_back(i);
  }
  try {
    compile_tape(s, syms, *impl);
  } catch (const BadConstant& bc) {
    fail_bad_constant(text, fe, syms, bc);
  }

  // Texts.
  impl->text = source_text(s.value);
  if (derivative_order >= 1)
    for (int i = 0; i < n; ++i) impl->grad_text.push_back(source_text(s.grad[i]));
  if (derivative_order >= 2)
    for (const GiNaC::ex& h : s.hess) impl->hess_text.push_back(source_text(h));

  if (options.extra_derivative_order > 0) {
    // ∂ᵏf/∂x_iᵏ over the same symbols (no new ones: see ExpressionOptions), value only.
    auto extra = std::make_shared<Impl>();
    extra->source = text;
    extra->variables = impl->variables;
    extra->n = n;
    extra->order = 0;
    Symbolic d;
    try {
      d.value = s.value.diff(syms[options.extra_derivative_variable], options.extra_derivative_order);
    } catch (const std::exception& err) {
      fail_at(text, std::string::npos, 0, std::string("differentiation failed (") + err.what() + ")", "");
    }
    for (int i = 0; i < n; ++i)
      if (d.value.has(syms[i])) d.used.push_back(i);
    extra->used = d.used;
    try {
      compile_tape(d, syms, *extra);
    } catch (const BadConstant& bc) {
      fail_bad_constant(text, fe, syms, bc);
    }
    extra->text = source_text(d.value);
    impl->extra_kernel = extra->select_kernel();
    impl->extra = std::move(extra);
  }

  kernel_ = impl->select_kernel();
  order_ = impl->order;
  raw_ = impl.get();
  impl_ = std::move(impl);
}

int Expression::num_variables() const { return impl_->n; }
const std::vector<std::string>& Expression::variables() const { return impl_->variables; }
std::vector<int> Expression::used_variables() const { return impl_->used; }
std::vector<int> Expression::referenced_variables() const { return impl_->referenced; }
int Expression::derivative_order() const { return impl_->order; }
const std::string& Expression::source() const { return impl_->source; }
int Expression::tape_size() const { return impl_->instructions; }
bool Expression::is_quadratic() const { return impl_->quad.active; }
int Expression::register_count() const { return impl_->registers; }
int Expression::tape_size_without_cse() const { return impl_->tape_without_cse; }

void Expression::throw_order_error(bool grad) const {
  const char* what = grad ? "gradient" : "Hessian";
  const int needed = grad ? 1 : 2;
  throw Error("Expression::evaluate: " + std::string(what) + " requested for \"" +
              impl_->source + "\", which was built with derivative_order " +
              std::to_string(order_) + " (hint: build it with derivative_order >= " +
              std::to_string(needed) + " or pass nullptr)");
}

void Expression::evaluate(const double* x, double& value, double* grad, double* hess,
                          ExpressionWorkspace& ws) const {
  if ((grad && order_ < 1) || (hess && order_ < 2)) throw_order_error(grad && order_ < 1);
  const Impl& m = *raw_;
  if (m.quad.active) return kernel_(m, x, value, grad, hess, nullptr);
  if (ws.registers_.size() < static_cast<std::size_t>(m.registers)) ws.reserve_for(*this);
  m.run_tape_program(x, ws.registers_.data(), value, grad, hess);
}

std::string Expression::text() const { return impl_->text; }

double Expression::extra_derivative(const double* x) const {
  if (!raw_->extra)
    throw Error("Expression::extra_derivative: \"" + raw_->source +
                "\" was built without one (hint: ExpressionOptions::extra_derivative_order >= 1)");
  double v;
  raw_->extra_kernel(*raw_->extra, x, v, nullptr, nullptr, nullptr);
  return v;
}

std::string Expression::extra_derivative_text() const {
  if (!impl_->extra)
    throw Error("Expression::extra_derivative_text: \"" + impl_->source +
                "\" was built without one (hint: ExpressionOptions::extra_derivative_order >= 1)");
  return impl_->extra->text;
}

std::string Expression::derivative_text(int i) const {
  if (impl_->order < 1)
    throw Error("Expression::derivative_text: \"" + impl_->source +
                "\" was built with derivative_order 0 (hint: build it with derivative_order >= 1)");
  if (i < 0 || i >= impl_->n)
    throw Error(expected_got("Expression::derivative_text index",
                             "0.." + std::to_string(impl_->n - 1), std::to_string(i)));
  return impl_->grad_text[i];
}

std::string Expression::second_derivative_text(int i, int j) const {
  if (impl_->order < 2)
    throw Error("Expression::second_derivative_text: \"" + impl_->source +
                "\" was built with derivative_order " + std::to_string(impl_->order) +
                " (hint: build it with derivative_order 2)");
  for (int k : {i, j})
    if (k < 0 || k >= impl_->n)
      throw Error(expected_got("Expression::second_derivative_text index",
                               "0.." + std::to_string(impl_->n - 1), std::to_string(k)));
  return impl_->hess_text[static_cast<std::size_t>(i) * impl_->n + j];
}

std::string Expression::tape_listing() const {
  const Impl& m = *impl_;
  std::ostringstream os;
  if (m.quad.active) os << "(evaluated by the quadratic kernel; tape kept for reference)\n";
  for (const Instr& in : m.code) {
    const OpInfo& oi = info(in.op);
    auto block = [&](const char* name, std::uint32_t index) {
      const OutBlock& bl = m.blocks[index];
      for (std::uint32_t k = 0; k < bl.dense_n; ++k) {
        const std::uint32_t src = m.sources[bl.d_off + k];
        os << name << "[" << k << "] = "
           << (src & kConstSource ? fmt(m.pool[src & ~kConstSource]) : "r" + std::to_string(src))
           << "\n";
      }
      if (bl.fill) os << name << "[0.." << bl.fill << ") = 0\n";
      for (std::uint32_t k = 0; k < bl.c_n; ++k)
        os << name << "[" << m.consts[bl.c_off + k].index << "] = " << fmt(m.consts[bl.c_off + k].value)
           << "\n";
      for (std::uint32_t k = 0; k < bl.r_n; ++k)
        os << name << "[" << m.slots[bl.r_off + k].index << "] = r" << m.slots[bl.r_off + k].reg
           << "\n";
    };
    switch (in.op) {
      case Op::LoadX:
        for (std::uint32_t k = 0; k < in.b; ++k)
          os << "r" << m.slots[in.a + k].reg << " = x[" << m.slots[in.a + k].index << "]\n";
        continue;
      case Op::ValueOut: os << "value = r" << in.a << "\n"; continue;
      case Op::ValueOutC: os << "value = " << fmt(in.c) << "\n"; continue;
      case Op::GradOut: case Op::GradOut1: case Op::GradOut2: case Op::GradOut3:
      case Op::GradOut4:
        os << "-- gradient out:\n";
        block("grad", in.a);
        continue;
      case Op::HessOut: case Op::HessOut1: case Op::HessOut4: case Op::HessOut9:
      case Op::HessOut16:
        os << "-- hessian out:\n";
        block("hess", in.a);
        continue;
      case Op::End: continue;
      default: break;
    }
    os << "r" << in.dst;
    if (in.op == Op::SinCos) os << ", r" << in.b;
    os << " = " << oi.name;
    if (oi.inputs >= 1) os << " r" << in.a;
    if (oi.inputs >= 2) os << " r" << in.b;
    if (in.op == Op::Select) {
      os << " r" << select_else(in.d) << "\n";
      continue;
    }
    if (is_function(in.op)) {
      if (in.c != 1.0 || in.d != 0.0) os << " (arg " << fmt(in.c) << "*a + " << fmt(in.d) << ")";
    } else {
      if (oi.immediates >= 1) os << " " << fmt(in.c);
      if (oi.immediates >= 2) os << " " << fmt(in.d);
    }
    os << "\n";
  }
  return os.str();
}

ExpressionWorkspace::ExpressionWorkspace(const Expression& e) { reserve_for(e); }

void ExpressionWorkspace::reserve_for(const Expression& e) {
  if (registers_.size() < static_cast<std::size_t>(e.register_count()))
    registers_.resize(e.register_count());
}

}  // namespace refdyn
