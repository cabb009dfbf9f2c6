// Expression engine: the tape interpreter over dual numbers (JacobianScalar), for exact
// Jacobians of quantities computed from an expression's value, gradient and Hessian (the
// constraints' evaluate_dual). The same program as the double interpreter (interpreter.cpp),
// instruction by instruction with the same semantics; comparisons, Sign and Select act on the
// value parts (the selection itself is not differentiated, as in the double engine). A separate
// loop rather than a template of the double one, so the double path keeps its code and speed.
// The quadratic kernel is not used: the tape is always present and equal to it.
#include "internal.hpp"

#include "refdyn/common/error.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace refdyn {
namespace expr_detail {
namespace {

using D = JacobianScalar;

/// c·a + d over a dual a (c, d constants).
inline D affine(const Instr& i, const D& a) {
  D u = a;
  u.v = i.c * a.v + i.d;
  for (auto& x : u.d) x *= i.c;
  return u;
}
/// a constant times a dual.
inline D times(double c, const D& a) {
  D u = a;
  u.v *= c;
  for (auto& x : u.d) x *= c;
  return u;
}

void write_block_dual(const OutBlock& bl, const ProgramView& pv, const D* r, D* out) {
  if (bl.dense_n == 0) {
    std::fill_n(out, bl.fill, D(0.0));
    for (std::uint32_t k = 0; k < bl.c_n; ++k) out[pv.consts[bl.c_off + k].index] = D(pv.consts[bl.c_off + k].value);
    for (std::uint32_t k = 0; k < bl.r_n; ++k) out[pv.slots[bl.r_off + k].index] = r[pv.slots[bl.r_off + k].reg];
    return;
  }
  const std::uint32_t* src = pv.sources + bl.d_off;
  for (std::uint32_t k = 0; k < bl.dense_n; ++k) {
    const std::uint32_t s = src[k];
    out[k] = (s & kConstSource) ? D(pv.pool[s & ~kConstSource]) : r[s];
  }
}

}  // namespace

void interpret_dual(const Expression::Impl& m, const D* x, D& value, D* grad, D* hess, D* r) {
  const ProgramView& pv = m.view;
  using ad::abs;
  for (const Instr* p = pv.code;; ++p) {
    const Instr& i = *p;
    switch (i.op) {
      case Op::Add: r[i.dst] = r[i.a] + r[i.b]; break;
      case Op::Sub: r[i.dst] = r[i.a] - r[i.b]; break;
      case Op::Mul: r[i.dst] = r[i.a] * r[i.b]; break;
      case Op::Div: r[i.dst] = r[i.a] / r[i.b]; break;
      case Op::Neg: r[i.dst] = -r[i.a]; break;
      case Op::AddC: r[i.dst] = r[i.a] + D(i.c); break;
      case Op::MulC: r[i.dst] = times(i.c, r[i.a]); break;
      case Op::RSubC: r[i.dst] = D(i.c) - r[i.a]; break;
      case Op::RDivC: r[i.dst] = D(i.c) / r[i.a]; break;
      case Op::Axpy: r[i.dst] = r[i.a] + times(i.c, r[i.b]); break;
      case Op::AxpyC: r[i.dst] = r[i.a] + times(i.c, r[i.b]) + D(i.d); break;
      case Op::AxpySq: {
        const D v = r[i.b];
        r[i.dst] = r[i.a] + times(i.c, v) * v;
        break;
      }
      case Op::Affine: r[i.dst] = affine(i, r[i.a]); break;
      case Op::Sq: {
        const D v = r[i.a];
        r[i.dst] = v * v;
        break;
      }
      case Op::SqAffine: {
        const D v = r[i.a];
        r[i.dst] = times(i.c, v) * v + D(i.d);
        break;
      }
      case Op::PowC: r[i.dst] = ad::pow(r[i.a], i.c); break;
      case Op::Pow: r[i.dst] = ad::pow(r[i.a], r[i.b]); break;
      case Op::Atan2: r[i.dst] = ad::atan2(r[i.a], r[i.b]); break;
      case Op::Const: r[i.dst] = D(i.c); break;
      case Op::Sqrt: r[i.dst] = ad::sqrt(affine(i, r[i.a])); break;
      case Op::Sin: r[i.dst] = ad::sin(affine(i, r[i.a])); break;
      case Op::Cos: r[i.dst] = ad::cos(affine(i, r[i.a])); break;
      case Op::SinCos: {
        const D u = affine(i, r[i.a]);
        r[i.dst] = ad::sin(u);
        r[i.b] = ad::cos(u);
        break;
      }
      case Op::Tan: r[i.dst] = ad::tan(affine(i, r[i.a])); break;
      case Op::Asin: r[i.dst] = ad::asin(affine(i, r[i.a])); break;
      case Op::Acos: r[i.dst] = ad::acos(affine(i, r[i.a])); break;
      case Op::Atan: r[i.dst] = ad::atan(affine(i, r[i.a])); break;
      case Op::Sinh: r[i.dst] = ad::sinh(affine(i, r[i.a])); break;
      case Op::Cosh: r[i.dst] = ad::cosh(affine(i, r[i.a])); break;
      case Op::Tanh: r[i.dst] = ad::tanh(affine(i, r[i.a])); break;
      case Op::Asinh: r[i.dst] = ad::asinh(affine(i, r[i.a])); break;
      case Op::Acosh: r[i.dst] = ad::acosh(affine(i, r[i.a])); break;
      case Op::Atanh: r[i.dst] = ad::atanh(affine(i, r[i.a])); break;
      case Op::Exp: r[i.dst] = ad::exp(affine(i, r[i.a])); break;
      case Op::Log: r[i.dst] = ad::log(affine(i, r[i.a])); break;
      case Op::Abs: r[i.dst] = ad::abs(affine(i, r[i.a])); break;
      case Op::Sign: r[i.dst] = D(i.c * r[i.a].v + i.d >= 0.0 ? 1.0 : -1.0); break;
      case Op::CmpLt: r[i.dst] = D(r[i.a].v < r[i.b].v ? 1.0 : 0.0); break;
      case Op::CmpLe: r[i.dst] = D(r[i.a].v <= r[i.b].v ? 1.0 : 0.0); break;
      case Op::Select: r[i.dst] = r[i.a].v != 0.0 ? r[i.b] : r[select_else(i.d)]; break;
      case Op::LoadX: {
        const OutputSlot* sl = pv.slots + i.a;
        for (std::uint32_t k = 0; k < i.b; ++k) r[sl[k].reg] = x[sl[k].index];
        break;
      }
      case Op::ValueOut:
        value = r[i.a];
        if (!grad && !hess) return;
        break;
      case Op::ValueOutC:
        value = D(i.c);
        if (!grad && !hess) return;
        break;
      case Op::GradOut:
        if (grad) write_block_dual(pv.blocks[i.a], pv, r, grad);
        if (!hess) return;
        break;
      case Op::GradOut1:
      case Op::GradOut2:
      case Op::GradOut3:
      case Op::GradOut4: {
        const int nd = static_cast<int>(i.op) - static_cast<int>(Op::GradOut1) + 1;
        if (grad)
          for (int k = 0; k < nd; ++k) {
            const std::uint32_t s = pv.sources[i.b + k];
            grad[k] = (s & kConstSource) ? D(pv.pool[s & ~kConstSource]) : r[s];
          }
        if (!hess) return;
        break;
      }
      case Op::HessOut: write_block_dual(pv.blocks[i.a], pv, r, hess); return;
      case Op::HessOut1:
      case Op::HessOut4:
      case Op::HessOut9:
      case Op::HessOut16: {
        const int nd = i.op == Op::HessOut1 ? 1 : i.op == Op::HessOut4 ? 4 : i.op == Op::HessOut9 ? 9 : 16;
        for (int k = 0; k < nd; ++k) {
          const std::uint32_t s = pv.sources[i.b + k];
          hess[k] = (s & kConstSource) ? D(pv.pool[s & ~kConstSource]) : r[s];
        }
        return;
      }
      case Op::End: return;
      case Op::Count: return;
    }
  }
}

}  // namespace expr_detail

using namespace expr_detail;

void Expression::evaluate(const JacobianScalar* x, JacobianScalar& value, JacobianScalar* grad,
                          JacobianScalar* hess, JacobianScalar* registers) const {
  if ((grad && order_ < 1) || (hess && order_ < 2)) throw_order_error(grad && order_ < 1);
  interpret_dual(*raw_, x, value, grad, hess, registers);
}

void Expression::evaluate(const JacobianScalar* x, JacobianScalar& value, JacobianScalar* grad,
                          JacobianScalar* hess, ExpressionDualWorkspace& ws) const {
  if (ws.registers_.size() < static_cast<std::size_t>(raw_->registers)) ws.reserve_for(*this);
  evaluate(x, value, grad, hess, ws.registers_.data());
}

void Expression::evaluate(const JacobianScalar* x, JacobianScalar& value, JacobianScalar* grad,
                          JacobianScalar* hess) const {
  thread_local ExpressionDualWorkspace ws;
  evaluate(x, value, grad, hess, ws);
}

ExpressionDualWorkspace::ExpressionDualWorkspace(const Expression& e) { reserve_for(e); }

void ExpressionDualWorkspace::reserve_for(const Expression& e) {
  if (registers_.size() < static_cast<std::size_t>(e.register_count()))
    registers_.resize(e.register_count());
}

}  // namespace refdyn
