// Expression engine, stage 4: the tape interpreter and the closed-form (quadratic) kernels.
#include "internal.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace refdyn {
namespace expr_detail {

/// Reference semantics of one instruction (constant folding; the interpreter mirrors it).
double apply(Op op, double a, double b, double c, double d) {
  const double u = c * a + d;
  switch (op) {
    case Op::Add: return a + b;
    case Op::Sub: return a - b;
    case Op::Mul: return a * b;
    case Op::Div: return a / b;
    case Op::Neg: return -a;
    case Op::AddC: return a + c;
    case Op::MulC: return a * c;
    case Op::RSubC: return c - a;
    case Op::RDivC: return c / a;
    case Op::Axpy: return a + c * b;
    case Op::AxpyC: return a + c * b + d;
    case Op::AxpySq: return a + c * b * b;
    case Op::Affine: return c * a + d;
    case Op::Sq: return a * a;
    case Op::SqAffine: return c * a * a + d;
    case Op::PowC: return std::pow(a, c);
    case Op::Pow: return std::pow(a, b);
    case Op::Atan2: return std::atan2(a, b);
    case Op::Const: return c;
    case Op::Sqrt: return std::sqrt(u);
    case Op::Sin: return std::sin(u);
    case Op::Cos: return std::cos(u);
    case Op::SinCos: return std::sin(u);
    case Op::Tan: return std::tan(u);
    case Op::Asin: return std::asin(u);
    case Op::Acos: return std::acos(u);
    case Op::Atan: return std::atan(u);
    case Op::Sinh: return std::sinh(u);
    case Op::Cosh: return std::cosh(u);
    case Op::Tanh: return std::tanh(u);
    case Op::Asinh: return std::asinh(u);
    case Op::Acosh: return std::acosh(u);
    case Op::Atanh: return std::atanh(u);
    case Op::Exp: return std::exp(u);
    case Op::Log: return std::log(u);
    case Op::Abs: return std::fabs(u);
    case Op::Sign: return u >= 0.0 ? 1.0 : -1.0;
    case Op::CmpLt: return a < b ? 1.0 : 0.0;
    case Op::CmpLe: return a <= b ? 1.0 : 0.0;
    default: break;
  }
  return 0.0;
}

namespace {

__attribute__((noinline)) void write_sparse(const OutBlock& bl, const ProgramView& pv,
                                            const double* r, double* out) {
  if (bl.fill) std::fill_n(out, bl.fill, 0.0);
  for (std::uint32_t k = 0; k < bl.c_n; ++k)
    out[pv.consts[bl.c_off + k].index] = pv.consts[bl.c_off + k].value;
  for (std::uint32_t k = 0; k < bl.r_n; ++k)
    out[pv.slots[bl.r_off + k].index] = r[pv.slots[bl.r_off + k].reg];
}

template <int N>
__attribute__((always_inline)) inline void write_dense(const std::uint32_t* src, const double* pool,
                                                       const double* r, double* out) {
  for (int k = 0; k < N; ++k) {
    const std::uint32_t s = src[k];
    const double* base = (s & kConstSource) ? pool : r;  // a select, not a branch
    out[k] = base[s & ~kConstSource];
  }
}

__attribute__((always_inline)) inline void write_block(const OutBlock& bl, const ProgramView& pv,
                                                       const double* r, double* out) {
  const std::uint32_t* src = pv.sources + bl.d_off;
  switch (bl.dense_n) {
    case 0: write_sparse(bl, pv, r, out); return;
    case 1: write_dense<1>(src, pv.pool, r, out); return;
    case 2: write_dense<2>(src, pv.pool, r, out); return;
    case 3: write_dense<3>(src, pv.pool, r, out); return;
    case 4: write_dense<4>(src, pv.pool, r, out); return;
    default:
      for (std::uint32_t k = 0; k < bl.dense_n; ++k) {
        const std::uint32_t s = src[k];
        out[k] = (s & kConstSource) ? pv.pool[s & ~kConstSource] : r[s];
      }
  }
}



// The interpreter: one pass over the whole program (loads, value, stores, gradient, ...,
// End). Registers r[]. The handlers are written once and expanded either as a direct-threaded
// label table (GCC/Clang: one indirect jump per handler, which predicts better than a single
// switch jump) or as a switch.
#define RD_HANDLERS                                                                   \
  RD_OP(Add) { r[p->dst] = r[p->a] + r[p->b]; }                                       \
  RD_NEXT;                                                                            \
  RD_OP(Sub) { r[p->dst] = r[p->a] - r[p->b]; }                                       \
  RD_NEXT;                                                                            \
  RD_OP(Mul) { r[p->dst] = r[p->a] * r[p->b]; }                                       \
  RD_NEXT;                                                                            \
  RD_OP(Div) { r[p->dst] = r[p->a] / r[p->b]; }                                       \
  RD_NEXT;                                                                            \
  RD_OP(Neg) { r[p->dst] = -r[p->a]; }                                                \
  RD_NEXT;                                                                            \
  RD_OP(AddC) { r[p->dst] = r[p->a] + p->c; }                                         \
  RD_NEXT;                                                                            \
  RD_OP(MulC) { r[p->dst] = r[p->a] * p->c; }                                         \
  RD_NEXT;                                                                            \
  RD_OP(RSubC) { r[p->dst] = p->c - r[p->a]; }                                        \
  RD_NEXT;                                                                            \
  RD_OP(RDivC) { r[p->dst] = p->c / r[p->a]; }                                        \
  RD_NEXT;                                                                            \
  RD_OP(Axpy) { r[p->dst] = r[p->a] + p->c * r[p->b]; }                               \
  RD_NEXT;                                                                            \
  RD_OP(AxpyC) { r[p->dst] = r[p->a] + p->c * r[p->b] + p->d; }                       \
  RD_NEXT;                                                                            \
  RD_OP(AxpySq) {                                                                     \
    const double v = r[p->b];                                                         \
    r[p->dst] = r[p->a] + p->c * v * v;                                               \
  }                                                                                   \
  RD_NEXT;                                                                            \
  RD_OP(Affine) { r[p->dst] = p->c * r[p->a] + p->d; }                                \
  RD_NEXT;                                                                            \
  RD_OP(Sq) {                                                                         \
    const double v = r[p->a];                                                         \
    r[p->dst] = v * v;                                                                \
  }                                                                                   \
  RD_NEXT;                                                                            \
  RD_OP(SqAffine) {                                                                   \
    const double v = r[p->a];                                                         \
    r[p->dst] = p->c * v * v + p->d;                                                  \
  }                                                                                   \
  RD_NEXT;                                                                            \
  RD_OP(PowC) { r[p->dst] = std::pow(r[p->a], p->c); }                                \
  RD_NEXT;                                                                            \
  RD_OP(Pow) { r[p->dst] = std::pow(r[p->a], r[p->b]); }                              \
  RD_NEXT;                                                                            \
  RD_OP(Atan2) { r[p->dst] = std::atan2(r[p->a], r[p->b]); }                          \
  RD_NEXT;                                                                            \
  RD_OP(Const) { r[p->dst] = p->c; }                                                  \
  RD_NEXT;                                                                            \
  RD_OP(Sqrt) { r[p->dst] = std::sqrt(RD_U); }                                        \
  RD_NEXT;                                                                            \
  RD_OP(Sin) { r[p->dst] = std::sin(RD_U); }                                          \
  RD_NEXT;                                                                            \
  RD_OP(Cos) { r[p->dst] = std::cos(RD_U); }                                          \
  RD_NEXT;                                                                            \
  RD_OP(SinCos) {                                                                     \
    double s_, c_;                                                                    \
    sin_cos(RD_U, s_, c_);                                                            \
    r[p->dst] = s_;                                                                   \
    r[p->b] = c_;                                                                     \
  }                                                                                   \
  RD_NEXT;                                                                            \
  RD_OP(Tan) { r[p->dst] = std::tan(RD_U); }                                          \
  RD_NEXT;                                                                            \
  RD_OP(Asin) { r[p->dst] = std::asin(RD_U); }                                        \
  RD_NEXT;                                                                            \
  RD_OP(Acos) { r[p->dst] = std::acos(RD_U); }                                        \
  RD_NEXT;                                                                            \
  RD_OP(Atan) { r[p->dst] = std::atan(RD_U); }                                        \
  RD_NEXT;                                                                            \
  RD_OP(Sinh) { r[p->dst] = std::sinh(RD_U); }                                        \
  RD_NEXT;                                                                            \
  RD_OP(Cosh) { r[p->dst] = std::cosh(RD_U); }                                        \
  RD_NEXT;                                                                            \
  RD_OP(Tanh) { r[p->dst] = std::tanh(RD_U); }                                        \
  RD_NEXT;                                                                            \
  RD_OP(Asinh) { r[p->dst] = std::asinh(RD_U); }                                      \
  RD_NEXT;                                                                            \
  RD_OP(Acosh) { r[p->dst] = std::acosh(RD_U); }                                      \
  RD_NEXT;                                                                            \
  RD_OP(Atanh) { r[p->dst] = std::atanh(RD_U); }                                      \
  RD_NEXT;                                                                            \
  RD_OP(Exp) { r[p->dst] = std::exp(RD_U); }                                          \
  RD_NEXT;                                                                            \
  RD_OP(Log) { r[p->dst] = std::log(RD_U); }                                          \
  RD_NEXT;                                                                            \
  RD_OP(Abs) { r[p->dst] = std::fabs(RD_U); }                                         \
  RD_NEXT;                                                                            \
  RD_OP(Sign) { r[p->dst] = RD_U >= 0.0 ? 1.0 : -1.0; }                               \
  RD_NEXT;                                                                            \
  RD_OP(CmpLt) { r[p->dst] = r[p->a] < r[p->b] ? 1.0 : 0.0; }                         \
  RD_NEXT;                                                                            \
  RD_OP(CmpLe) { r[p->dst] = r[p->a] <= r[p->b] ? 1.0 : 0.0; }                        \
  RD_NEXT;                                                                            \
  RD_OP(Select) {                                                                     \
    r[p->dst] = r[p->a] != 0.0 ? r[p->b] : r[select_else(p->d)];                      \
  }                                                                                   \
  RD_NEXT;                                                                            \
  RD_OP(LoadX) {                                                                      \
    const OutputSlot* sl = pv.slots + p->a;                                           \
    switch (p->b) {                                                                   \
      case 2: r[sl[1].reg] = x[sl[1].index]; [[fallthrough]];                         \
      case 1: r[sl[0].reg] = x[sl[0].index]; break;                                   \
      default:                                                                        \
        for (std::uint32_t k = 0; k < p->b; ++k) r[sl[k].reg] = x[sl[k].index];       \
    }                                                                                 \
  }                                                                                   \
  RD_NEXT;                                                                            \
  RD_OP(ValueOut) {                                                                   \
    value = r[p->a];                                                                  \
    if (!grad && !hess) return;                                                       \
  }                                                                                   \
  RD_NEXT;                                                                            \
  RD_OP(ValueOutC) {                                                                  \
    value = p->c;                                                                     \
    if (!grad && !hess) return;                                                       \
  }                                                                                   \
  RD_NEXT;                                                                            \
  RD_OP(GradOut) {                                                                    \
    if (grad) write_block(pv.blocks[p->a], pv, r, grad);                              \
    if (!hess) return;                                                                \
  }                                                                                   \
  RD_NEXT;                                                                            \
  RD_OP(GradOut1) { RD_GRAD_DENSE(1); }                                               \
  RD_NEXT;                                                                            \
  RD_OP(GradOut2) { RD_GRAD_DENSE(2); }                                               \
  RD_NEXT;                                                                            \
  RD_OP(GradOut3) { RD_GRAD_DENSE(3); }                                               \
  RD_NEXT;                                                                            \
  RD_OP(GradOut4) { RD_GRAD_DENSE(4); }                                               \
  RD_NEXT;                                                                            \
  RD_OP(HessOut) {                                                                    \
    write_block(pv.blocks[p->a], pv, r, hess);                                        \
    return;                                                                           \
  }                                                                                   \
  RD_OP(HessOut1) { RD_HESS_DENSE(1); }                                               \
  RD_OP(HessOut4) { RD_HESS_DENSE(4); }                                               \
  RD_OP(HessOut9) { RD_HESS_DENSE(9); }                                               \
  RD_OP(HessOut16) { RD_HESS_DENSE(16); }                                             \
  RD_OP(End) { return; }

#define RD_U (p->c * r[p->a] + p->d)
#define RD_GRAD_DENSE(N)                                              \
  if (grad) write_dense<N>(pv.sources + p->b, pv.pool, r, grad); \
  if (!hess) return
#define RD_HESS_DENSE(N)                                 \
  write_dense<N>(pv.sources + p->b, pv.pool, r, hess); \
  return
// OwnStack: registers on this function's stack (the program needs at most kStackRegisters),
// else in `scratch`.
template <bool OwnStack>
void interpret(
    const Expression::Impl& m, const double* __restrict x, double& value, double* grad,
    double* hess, double* scratch) {
  double own[OwnStack ? Expression::kStackRegisters : 1];
  double* __restrict r = OwnStack ? own : scratch;
  const ProgramView& pv = m.view;
  const Instr* p = pv.code;
#if defined(__GNUC__) && !defined(REFDYN_EXPRESSION_SWITCH_DISPATCH)
  static const void* const kLabels[] = {
      &&L_Add,    &&L_Sub,    &&L_Mul,    &&L_Div,     &&L_Neg,     &&L_AddC,
      &&L_MulC,   &&L_RSubC,  &&L_RDivC,  &&L_Axpy,    &&L_AxpyC,   &&L_AxpySq,
      &&L_Affine, &&L_Sq,     &&L_SqAffine, &&L_PowC,  &&L_Pow,     &&L_Atan2,
      &&L_Const,  &&L_Sqrt,   &&L_Sin,    &&L_Cos,     &&L_SinCos,  &&L_Tan,
      &&L_Asin,   &&L_Acos,   &&L_Atan,   &&L_Sinh,    &&L_Cosh,    &&L_Tanh,
      &&L_Asinh,  &&L_Acosh,  &&L_Atanh,  &&L_Exp,     &&L_Log,     &&L_Abs,
      &&L_Sign,   &&L_CmpLt,  &&L_CmpLe,  &&L_Select,
      &&L_LoadX,  &&L_ValueOut, &&L_ValueOutC, &&L_GradOut, &&L_GradOut1, &&L_GradOut2,
      &&L_GradOut3, &&L_GradOut4, &&L_HessOut, &&L_HessOut1, &&L_HessOut4, &&L_HessOut9,
      &&L_HessOut16, &&L_End};
  static_assert(sizeof(kLabels) / sizeof(kLabels[0]) == static_cast<int>(Op::Count));
#define RD_OP(name) L_##name:
#define RD_NEXT goto* kLabels[static_cast<int>((++p)->op)]
  goto* kLabels[static_cast<int>(p->op)];
  RD_HANDLERS
#undef RD_OP
#undef RD_NEXT
#else
  for (;; ++p) {
    switch (p->op) {
#define RD_OP(name) case Op::name:
#define RD_NEXT break
      RD_HANDLERS
#undef RD_OP
#undef RD_NEXT
      case Op::Count: return;
    }
  }
#endif
}
#undef RD_U
#undef RD_GRAD_DENSE
#undef RD_HESS_DENSE
#undef RD_HANDLERS

using Impl = Expression::Impl;

void kernel_tape_heap(const Impl& m, const double* x, double& value, double* grad,
                      double* hess, double*) {
  thread_local std::vector<double> big;
  if (big.size() < static_cast<std::size_t>(m.registers)) big.resize(m.registers);
  interpret<false>(m, x, value, grad, hess, big.data());
}

/// Quadratic kernel, all M variables used in order (compile-time size, fully unrolled).
/// Diagonal: A is diagonal; Linear: b != 0.
template <int M, bool Diagonal, bool Linear>
void kernel_quadratic_fixed(const Impl& m, const double* x, double& value, double* grad,
                            double* hess, double*) {
  const Quadratic& q = m.quad;
  double g[M];
  double v = q.c0;
  for (int k = 0; k < M; ++k) {
    double h;
    if constexpr (Diagonal) {
      h = q.A[k * M + k] * x[k];
    } else {
      h = 0.0;
      for (int l = 0; l < M; ++l) h += q.A[k * M + l] * x[l];
    }
    if constexpr (Linear) {
      g[k] = q.b[k] + h;
      v += x[k] * (q.b[k] + 0.5 * h);
    } else {
      g[k] = h;
      v += 0.5 * x[k] * h;
    }
  }
  value = v;
  if (grad)
    for (int k = 0; k < M; ++k) grad[k] = g[k];
  if (hess)
    for (int k = 0; k < M * M; ++k) hess[k] = q.A[k];
}

/// Quadratic kernel, general layout (some variables unused).
void kernel_quadratic(const Impl& m, const double* x, double& value, double* grad,
                      double* hess, double*) {
  const Quadratic& q = m.quad;
  const int mm = q.m;
  double xs[kMaxQuadratic], g[kMaxQuadratic];
  for (int k = 0; k < mm; ++k) xs[k] = x[q.u[k]];
  double v = q.c0;
  for (int k = 0; k < mm; ++k) {
    double h = 0.0;
    for (int l = 0; l < mm; ++l) h += q.A[k * mm + l] * xs[l];
    g[k] = q.b[k] + h;
    v += xs[k] * (q.b[k] + 0.5 * h);
  }
  value = v;
  if (grad) {
    for (const ConstSlot& o : m.grad_const) grad[o.index] = 0.0;
    for (int k = 0; k < mm; ++k) grad[q.u[k]] = g[k];
  }
  if (hess)
    for (const ConstSlot& o : m.hess_const) hess[o.index] = o.value;
}

template <bool Diagonal, bool Linear>
Expression::Kernel fixed_kernel(int m) {
  switch (m) {
    case 1: return kernel_quadratic_fixed<1, Diagonal, Linear>;
    case 2: return kernel_quadratic_fixed<2, Diagonal, Linear>;
    case 3: return kernel_quadratic_fixed<3, Diagonal, Linear>;
    case 4: return kernel_quadratic_fixed<4, Diagonal, Linear>;
    default: return nullptr;
  }
}

}  // namespace
}  // namespace expr_detail

using namespace expr_detail;

Expression::Kernel Expression::Impl::select_kernel() const {
  if (quad.active) {
    if (quad.identity) {
      bool linear = false;
      for (int k = 0; k < quad.m; ++k) linear = linear || quad.b[k] != 0.0;
      Expression::Kernel k = quad.diagonal ? (linear ? fixed_kernel<true, true>(quad.m)
                                                     : fixed_kernel<true, false>(quad.m))
                                           : (linear ? fixed_kernel<false, true>(quad.m)
                                                     : fixed_kernel<false, false>(quad.m));
      if (k) return k;
    }
    return kernel_quadratic;
  }
  return registers <= Expression::kStackRegisters ? interpret<true> : kernel_tape_heap;
}

void Expression::Impl::run_tape_program(const double* x, double* r, double& value, double* grad,
                                        double* hess) const {
  interpret<false>(*this, x, value, grad, hess, r);
}

}  // namespace refdyn
