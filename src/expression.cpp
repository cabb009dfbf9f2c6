// Expression engine: front end (names, precedence, error positions) -> GiNaC parser -> exact
// derivatives (GiNaC) -> tape compiler (CSE, constant folding, fused ops, register allocation)
// -> interpreter.
#include "refdyn/expression.hpp"

#include "refdyn/error.hpp"
#include "refdyn/text.hpp"

#include <cln/float.h>
#include <ginac/ginac.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <initializer_list>
#include <mutex>
#include <queue>
#include <set>
#include <sstream>
#include <tuple>

namespace refdyn {

// ------------------------------------------------------------------------------------------
// Tape
// ------------------------------------------------------------------------------------------
namespace {

enum class Op : std::uint8_t {
  // Arithmetic. c, d are immediates.
  Add,       // a + b
  Sub,       // a - b
  Mul,       // a * b
  Div,       // a / b
  Neg,       // -a
  AddC,      // a + c
  MulC,      // a * c
  RSubC,     // c - a
  RDivC,     // c / a
  Axpy,      // a + c*b
  AxpyC,     // a + c*b + d
  AxpySq,    // a + c*b*b
  Affine,    // c*a + d
  Sq,        // a*a
  SqAffine,  // c*a*a + d
  PowC,      // pow(a, c)
  Pow,       // pow(a, b)
  Atan2,     // atan2(a, b)
  Const,     // c
  // Functions of the affine argument u = c*a + d (c = 1, d = 0 unless a scaling was fused).
  Sqrt,
  Sin,
  Cos,
  SinCos,  // dst = sin(u), b = cos(u)
  Tan,
  Asin,
  Acos,
  Atan,
  Sinh,
  Cosh,
  Tanh,
  Asinh,
  Acosh,
  Atanh,
  Exp,
  Log,
  Abs,
  // Program I/O and control (emitted by the lowering, not by the compiler).
  LoadX,      // r[slot.reg] = x[slot.index] for b slots from slots[a]
  ValueOut,   // value = r[a]; return unless a derivative is wanted
  ValueOutC,  // value = c;    return unless a derivative is wanted
  GradOut,    // if grad: write output block a into grad; return unless hess is wanted
  GradOut1,   // as GradOut for a dense gradient of 1..4 entries with sources from b
  GradOut2,
  GradOut3,
  GradOut4,
  HessOut,    // write output block a into hess; return
  HessOut1,   // as HessOut for a dense Hessian of 1, 4, 9, 16 entries with sources from b
  HessOut4,
  HessOut9,
  HessOut16,
  End,        // return
  Count
};

struct OpInfo {
  const char* name;
  int inputs;  // register inputs: a (1) or a, b (2); 0 for Const/End
  int immediates;
};

constexpr std::array<OpInfo, static_cast<int>(Op::Count)> kOpInfo{{
    {"add", 2, 0},    {"sub", 2, 0},    {"mul", 2, 0},      {"div", 2, 0},     {"neg", 1, 0},
    {"addc", 1, 1},   {"mulc", 1, 1},   {"rsubc", 1, 1},    {"rdivc", 1, 1},   {"axpy", 2, 1},
    {"axpyc", 2, 2},  {"axpysq", 2, 1}, {"affine", 1, 2},   {"sq", 1, 0},      {"sqaffine", 1, 2},
    {"powc", 1, 1},   {"pow", 2, 0},    {"atan2", 2, 0},    {"const", 0, 1},   {"sqrt", 1, 2},
    {"sin", 1, 2},    {"cos", 1, 2},    {"sincos", 1, 2},   {"tan", 1, 2},     {"asin", 1, 2},
    {"acos", 1, 2},   {"atan", 1, 2},   {"sinh", 1, 2},     {"cosh", 1, 2},    {"tanh", 1, 2},
    {"asinh", 1, 2},  {"acosh", 1, 2},  {"atanh", 1, 2},    {"exp", 1, 2},     {"log", 1, 2},
    {"abs", 1, 2},    {"loadx", 0, 0}, {"value_out", 1, 0}, {"value_out_c", 0, 1},
    {"grad_out", 0, 0}, {"grad_out", 0, 0}, {"grad_out", 0, 0}, {"grad_out", 0, 0},
    {"grad_out", 0, 0}, {"hess_out", 0, 0}, {"hess_out", 0, 0}, {"hess_out", 0, 0},
    {"hess_out", 0, 0}, {"hess_out", 0, 0}, {"end", 0, 0},
}};

const OpInfo& info(Op op) { return kOpInfo[static_cast<int>(op)]; }
bool is_function(Op op) { return op >= Op::Sqrt && op <= Op::Abs; }

struct Instr {
  Op op;
  std::uint32_t dst;
  std::uint32_t a;
  std::uint32_t b;  // second input, or second output of SinCos
  double c;
  double d;
};

inline void sin_cos(double x, double& s, double& c) {
#if defined(__GLIBC__)
  ::sincos(x, &s, &c);
#else
  s = std::sin(x);
  c = std::cos(x);
#endif
}

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
    default: break;
  }
  return 0.0;
}

struct OutputSlot {
  std::uint32_t index;  // into x (loads), grad (i) or hess (i*n + j)
  std::uint32_t reg;
};

struct ConstSlot {
  std::uint32_t index;
  double value;
};

/// The writes of one output (gradient or Hessian), one of two layouts:
/// dense  (dense_n > 0): out[k] = source sources[d_off + k] for k < dense_n, a source being a
///        register index or kConstSource | index into the constant pool;
/// sparse: zero fill of the first `fill` entries, then constant entries consts[c_off, +c_n),
///        then register entries slots[r_off, +r_n) (large, mostly-zero Hessians).
struct OutBlock {
  std::uint32_t dense_n = 0, d_off = 0;
  std::uint32_t fill = 0;
  std::uint32_t c_off = 0, c_n = 0, r_off = 0, r_n = 0;
};
constexpr std::uint32_t kConstSource = 0x80000000u;
constexpr std::size_t kMaxDenseOutput = 64;

/// Arrays the interpreter reads.
struct ProgramView {
  const Instr* code = nullptr;
  const OutputSlot* slots = nullptr;
  const ConstSlot* consts = nullptr;
  const OutBlock* blocks = nullptr;
  const std::uint32_t* sources = nullptr;
  const double* pool = nullptr;
};

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


constexpr int kMaxQuadratic = 8;

/// Closed form for expressions whose Hessian is constant (polynomials of degree <= 2):
/// with h = A·xs over the used variables xs, g = b + h and value = c0 + xs·(b + h/2).
struct Quadratic {
  bool active = false;
  bool identity = false;  // every variable used, in order (n == m)
  bool diagonal = false;  // A diagonal
  int m = 0;
  double c0 = 0.0;
  std::array<std::uint32_t, kMaxQuadratic> u{};                 // used variable indices
  std::array<double, kMaxQuadratic> b{};                         // m
  std::array<double, kMaxQuadratic * kMaxQuadratic> A{};         // m*m, row-major
};

}  // namespace

struct Expression::Impl {
  std::string source;
  std::vector<std::string> variables;
  int order = 2;
  int n = 0;
  std::vector<int> used;

  // The program: loads, value stage, value store, exit if no derivatives wanted, gradient
  // stage, gradient stores (skipped without grad), exit if no Hessian wanted, Hessian stage,
  // Hessian stores, End.
  std::vector<Instr> code;
  int instructions = 0;  // arithmetic instructions (the tape proper: no loads/stores/control)
  int registers = 0;
  int tape_without_cse = 0;

  std::vector<OutputSlot> slots;      // loads and register outputs (see OutBlock)
  std::vector<ConstSlot> consts;      // constant outputs written by GradOut/HessOut
  std::vector<OutBlock> blocks;       // [gradient, Hessian]
  std::vector<std::uint32_t> sources; // dense output sources
  std::vector<double> pool;           // constants of dense outputs
  ProgramView view;                   // pointers into the vectors above (set once built)
  std::vector<ConstSlot> grad_const;  // constant (incl. zero) gradient entries
  std::vector<ConstSlot> hess_const;  // constant (incl. zero) Hessian entries

  Quadratic quad;

  std::string text;
  std::vector<std::string> grad_text;
  std::vector<std::string> hess_text;  // n*n, filled when order >= 2

  /// The tape interpreter with caller-provided registers r (size >= registers).
  void run_tape_program(const double* x, double* r, double& value, double* grad,
                        double* hess) const;
  /// The kernel for this expression.
  Expression::Kernel select_kernel() const;
};

namespace {

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

}  // namespace

namespace {

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

// ------------------------------------------------------------------------------------------
// Front end: lexer and recursive-descent parser producing a fully parenthesised text for GiNaC
// ------------------------------------------------------------------------------------------
namespace {

using GiNaC::ex;

struct FunctionSpec {
  const char* name;
  int arity;
};
constexpr FunctionSpec kFunctions[] = {
    {"sin", 1},   {"cos", 1},   {"tan", 1},   {"asin", 1}, {"acos", 1}, {"atan", 1},
    {"atan2", 2}, {"sinh", 1},  {"cosh", 1},  {"tanh", 1}, {"asinh", 1}, {"acosh", 1},
    {"atanh", 1}, {"exp", 1},   {"log", 1},   {"sqrt", 1}, {"abs", 1},  {"pow", 2},
    {"min", 2},   {"max", 2},
};

const FunctionSpec* find_function(const std::string& name) {
  for (const auto& f : kFunctions)
    if (name == f.name) return &f;
  return nullptr;
}

std::string function_list() {
  std::string s;
  for (const auto& f : kFunctions) {
    if (!s.empty()) s += ", ";
    s += f.name;
  }
  return s;
}

std::string strip_spaces(const std::string& s) {
  std::string out;
  for (char ch : s)
    if (!std::isspace(static_cast<unsigned char>(ch))) out += ch;
  return out;
}

bool is_ident_start(char ch) { return std::isalpha(static_cast<unsigned char>(ch)) || ch == '_'; }
bool is_ident_char(char ch) { return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_'; }

/// "expression "TEXT": WHAT at column C\n    TEXT\n    ^^^\n(hint: HINT)"
[[noreturn]] void fail_at(const std::string& text, std::size_t pos, std::size_t len,
                          const std::string& what, const std::string& hint) {
  std::string msg = "expression \"" + text + "\": " + what;
  if (pos != std::string::npos) {
    msg += " at column " + std::to_string(pos + 1) + "\n    " + text + "\n    ";
    msg += std::string(pos, ' ') + std::string(std::max<std::size_t>(len, 1), '^');
    msg += "\n";
  } else {
    msg += " ";
  }
  if (!hint.empty()) msg += "(hint: " + hint + ")";
  throw Error(msg);
}

enum class Tok { Num, Id, LParen, RParen, Comma, Plus, Minus, Star, Slash, Caret, End };

struct Token {
  Tok kind;
  std::size_t pos;
  std::size_t len;
  std::string s;
};

std::vector<Token> lex(const std::string& text) {
  std::vector<Token> out;
  std::size_t i = 0, n = text.size();
  while (i < n) {
    char ch = text[i];
    if (std::isspace(static_cast<unsigned char>(ch))) {
      ++i;
      continue;
    }
    std::size_t start = i;
    auto digit = [&](std::size_t k) {
      return k < n && std::isdigit(static_cast<unsigned char>(text[k]));
    };
    if (digit(i) || (ch == '.' && digit(i + 1))) {
      while (digit(i)) ++i;
      if (i < n && text[i] == '.') {
        ++i;
        while (digit(i)) ++i;
      }
      if (i < n && (text[i] == 'e' || text[i] == 'E')) {
        std::size_t k = i + 1;
        if (k < n && (text[k] == '+' || text[k] == '-')) ++k;
        if (digit(k)) {
          i = k;
          while (digit(i)) ++i;
        }
      }
      out.push_back({Tok::Num, start, i - start, text.substr(start, i - start)});
      continue;
    }
    if (is_ident_start(ch)) {
      while (i < n && is_ident_char(text[i])) ++i;
      out.push_back({Tok::Id, start, i - start, text.substr(start, i - start)});
      continue;
    }
    Tok k;
    std::size_t len = 1;
    switch (ch) {
      case '(': k = Tok::LParen; break;
      case ')': k = Tok::RParen; break;
      case ',': k = Tok::Comma; break;
      case '+': k = Tok::Plus; break;
      case '-': k = Tok::Minus; break;
      case '/': k = Tok::Slash; break;
      case '^': k = Tok::Caret; break;
      case '*':
        if (i + 1 < n && text[i + 1] == '*') {
          k = Tok::Caret;
          len = 2;
        } else {
          k = Tok::Star;
        }
        break;
      default:
        fail_at(text, i, 1, std::string("unexpected character '") + ch + "'",
                "expressions use numbers, names, + - * / ^, parentheses and function calls");
    }
    out.push_back({k, start, len, text.substr(start, len)});
    i += len;
  }
  out.push_back({Tok::End, n, 0, ""});
  return out;
}

std::string describe(const Token& t) {
  if (t.kind == Tok::End) return "end of expression";
  return "'" + t.s + "'";
}

/// A sub-expression of the source, with its GiNaC text; used to locate evaluation errors.
struct Node {
  std::size_t pos, end;
  std::string ginac_text;
};

struct FrontEnd {
  const std::string& text;
  const std::vector<std::string>& variables;           // stripped names
  const std::map<std::string, double>& parameters;
  std::vector<Token> toks;
  std::size_t k = 0;
  GiNaC::symtab symtab;
  const std::vector<GiNaC::realsymbol>& symbols;       // per variable
  std::vector<Node> nodes;
  std::map<std::string, double> used_parameters;

  FrontEnd(const std::string& t, const std::vector<std::string>& v,
           const std::map<std::string, double>& p, const std::vector<GiNaC::realsymbol>& syms)
      : text(t), variables(v), parameters(p), symbols(syms) {
    toks = lex(text);
  }

  const Token& peek(std::size_t ahead = 0) const {
    return toks[std::min(k + ahead, toks.size() - 1)];
  }
  const Token& next() { return toks[k < toks.size() - 1 ? k++ : k]; }

  [[noreturn]] void error_at(const Token& t, const std::string& what, const std::string& hint) {
    fail_at(text, t.pos, t.kind == Tok::End ? 1 : t.len, what, hint);
  }

  void expect(Tok kind, const std::string& what) {
    const Token& t = peek();
    if (t.kind != kind) {
      std::string hint = kind == Tok::RParen ? "check that parentheses are balanced"
                                             : "check the syntax near this point";
      error_at(t, "expected " + what + ", got " + describe(t), hint);
    }
    next();
  }

  std::string record(std::size_t start_tok, const std::string& g) {
    std::size_t pos = toks[start_tok].pos;
    const Token& last = toks[k > 0 ? k - 1 : 0];
    nodes.push_back({pos, last.pos + last.len, g});
    return g;
  }

  std::string parse() {
    std::string g = parse_sum();
    const Token& t = peek();
    if (t.kind != Tok::End) {
      std::string hint = t.kind == Tok::RParen
                             ? "unbalanced ')'"
                             : "an operator is missing (implicit multiplication like '2x' is "
                               "not supported; write '2*x')";
      error_at(t, "unexpected " + describe(t), hint);
    }
    return g;
  }

  std::string parse_sum() {
    std::size_t start = k;
    std::string s = parse_product();
    while (peek().kind == Tok::Plus || peek().kind == Tok::Minus) {
      char op = next().kind == Tok::Plus ? '+' : '-';
      std::string t = parse_product();
      s = record(start, "(" + s + op + t + ")");
    }
    return s;
  }

  std::string parse_product() {
    std::size_t start = k;
    std::string s = parse_unary();
    while (peek().kind == Tok::Star || peek().kind == Tok::Slash) {
      char op = next().kind == Tok::Star ? '*' : '/';
      std::string t = parse_unary();
      s = record(start, "(" + s + op + t + ")");
    }
    return s;
  }

  std::string parse_unary() {
    std::size_t start = k;
    if (peek().kind == Tok::Plus) {
      next();
      return parse_unary();
    }
    if (peek().kind == Tok::Minus) {
      next();
      std::string s = parse_unary();
      return record(start, "(-" + s + ")");
    }
    return parse_power();
  }

  std::string parse_power() {
    std::size_t start = k;
    std::string b = parse_primary();
    if (peek().kind == Tok::Caret) {
      next();
      std::string e = parse_unary();  // right-associative, allows x^-2
      return record(start, "(" + b + "^" + e + ")");
    }
    return b;
  }

  // Index of the ')' matching the '(' at token index `open`, or npos.
  std::size_t matching_paren(std::size_t open) const {
    int depth = 0;
    for (std::size_t i = open; i < toks.size(); ++i) {
      if (toks[i].kind == Tok::LParen) ++depth;
      if (toks[i].kind == Tok::RParen && --depth == 0) return i;
    }
    return std::string::npos;
  }

  std::vector<std::string> candidates() const {
    std::vector<std::string> c = variables;
    for (const auto& [name, v] : parameters) c.push_back(name);
    c.push_back("pi");
    c.push_back("e");
    for (const auto& f : kFunctions) c.push_back(f.name);
    return c;
  }

  std::string identifiers_hint() const {
    return "identifiers must be variables listed by the caller, parameters, the constants pi "
           "and e, or the functions " +
           function_list();
  }

  std::string variable_placeholder(int index) {
    std::string ph = "rdvar" + std::to_string(index);
    symtab[ph] = symbols[index];
    return ph;
  }

  std::string parse_primary() {
    std::size_t start = k;
    const Token& t = peek();
    switch (t.kind) {
      case Tok::Num:
        next();
        return "(" + t.s + ")";
      case Tok::LParen: {
        next();
        std::string s = parse_sum();
        expect(Tok::RParen, "')' to close the '(' at column " + std::to_string(t.pos + 1));
        return record(start, "(" + s + ")");
      }
      case Tok::Id:
        return parse_identifier();
      default:
        error_at(t, "expected a number, a name or '(', got " + describe(t),
                 t.kind == Tok::End ? "the expression ends too early"
                                    : "check the syntax near this point");
    }
  }

  std::string parse_identifier() {
    std::size_t start = k;
    const Token id = next();
    if (peek().kind == Tok::LParen) {
      std::size_t open = k;
      std::size_t close = matching_paren(open);
      if (close == std::string::npos)
        error_at(toks[open], "unclosed '('", "check that parentheses are balanced");
      std::string call = strip_spaces(text.substr(id.pos, toks[close].pos + 1 - id.pos));
      auto it = std::find(variables.begin(), variables.end(), call);
      if (it != variables.end()) {
        k = close + 1;
        return variable_placeholder(static_cast<int>(it - variables.begin()));
      }
      const FunctionSpec* f = find_function(id.s);
      if (!f) {
        // Unknown: a variable that is not listed or a misspelt function, whichever is closer.
        int best_var = 1 << 30, best_fn = 1 << 30;
        std::string var_name, fn_name;
        for (const std::string& v : variables) {
          int d = edit_distance(call, v);
          if (d < best_var) best_var = d, var_name = v;
        }
        for (const auto& fs : kFunctions) {
          int d = edit_distance(id.s, fs.name);
          if (d < best_fn) best_fn = d, fn_name = fs.name;
        }
        const int allowed_var = std::max<int>(2, static_cast<int>(call.size()) / 3);
        const int allowed_fn = std::max<int>(2, static_cast<int>(id.s.size()) / 3);
        std::string suggestion;
        if (best_var <= allowed_var && best_var <= best_fn)
          suggestion = " (did you mean '" + var_name + "'?)";
        else if (best_fn <= allowed_fn)
          suggestion = " (did you mean the function '" + fn_name + "'?)";
        else
          suggestion = did_you_mean(call, candidates());
        fail_at(text, id.pos, toks[close].pos + 1 - id.pos,
                "unknown identifier '" + call + "'" + suggestion, identifiers_hint());
      }
      next();  // '('
      std::vector<std::string> args;
      if (peek().kind != Tok::RParen) {
        args.push_back(parse_sum());
        while (peek().kind == Tok::Comma) {
          next();
          args.push_back(parse_sum());
        }
      }
      if (peek().kind != Tok::RParen)
        error_at(peek(), "expected ',' or ')' in the arguments of " + id.s + "(), got " +
                             describe(peek()),
                 "check that parentheses are balanced");
      next();
      if (static_cast<int>(args.size()) != f->arity)
        fail_at(text, id.pos, toks[k - 1].pos + 1 - id.pos,
                "function '" + id.s + "' takes " + std::to_string(f->arity) + " argument" +
                    (f->arity == 1 ? "" : "s") + ", got " + std::to_string(args.size()),
                f->arity == 1 ? "write " + id.s + "(u)" : "write " + id.s + "(u, v)");
      std::string g;
      const std::string name = id.s;
      if (name == "min" || name == "max") {
        const char* sign = name == "min" ? "-" : "+";
        g = "(((" + args[0] + ")+(" + args[1] + ")" + sign + "abs((" + args[0] + ")-(" +
            args[1] + ")))/2)";
      } else if (name == "pow") {
        g = "((" + args[0] + ")^(" + args[1] + "))";
      } else {
        g = name + "(" + args[0];
        for (std::size_t i = 1; i < args.size(); ++i) g += "," + args[i];
        g += ")";
      }
      return record(start, g);
    }
    // Plain identifier.
    auto it = std::find(variables.begin(), variables.end(), id.s);
    if (it != variables.end()) return variable_placeholder(static_cast<int>(it - variables.begin()));
    auto p = parameters.find(id.s);
    if (p != parameters.end()) {
      double v = p->second;
      if (!std::isfinite(v))
        error_at(id, "parameter '" + id.s + "' is " + fmt(v),
                 "give the parameter a finite value before building the expression");
      used_parameters[id.s] = v;
      std::string ph = "rdpar_" + id.s;
      if (v == std::trunc(v) && std::fabs(v) < 9007199254740992.0)
        symtab[ph] = GiNaC::numeric(static_cast<long>(v));
      else
        symtab[ph] = GiNaC::numeric(cln::cl_float(v, cln::float_format_dfloat));
      return ph;
    }
    if (id.s == "pi") {
      symtab["rdpi"] = GiNaC::Pi;
      return "rdpi";
    }
    if (id.s == "e") {
      symtab["rde"] = GiNaC::exp(ex(1));
      return "rde";
    }
    if (find_function(id.s))
      error_at(id, "function '" + id.s + "' used without arguments",
               "call it as " + id.s + "(...)");
    error_at(id, "unknown identifier '" + id.s + "'" + did_you_mean(id.s, candidates()),
             identifiers_hint());
  }
};

// ------------------------------------------------------------------------------------------
// Compiler: GiNaC expressions -> SSA tape -> register-allocated tape
// ------------------------------------------------------------------------------------------

bool has_symbol(const ex& e) {
  if (GiNaC::is_a<GiNaC::symbol>(e)) return true;
  for (std::size_t i = 0; i < e.nops(); ++i)
    if (has_symbol(e.op(i))) return true;
  return false;
}

std::string to_text(const ex& e) {
  std::ostringstream os;
  os << e;
  return os.str();
}

/// Thrown by the compiler for a constant that is not a finite real number; the constructor
/// turns it into an Error with a location.
struct BadConstant {
  std::string what;      // description
  std::string constant;  // GiNaC text of the constant
  bool infinite;
};

double constant_value(const ex& e) {
  ex v;
  try {
    v = e.evalf();
  } catch (const std::exception& err) {
    throw BadConstant{std::string("cannot be evaluated (") + err.what() + ")", to_text(e), true};
  }
  if (!GiNaC::is_a<GiNaC::numeric>(v))
    throw BadConstant{"does not evaluate to a number (got " + to_text(v) + ")", to_text(e), false};
  const GiNaC::numeric& num = GiNaC::ex_to<GiNaC::numeric>(v);
  if (!num.is_real())
    throw BadConstant{"is not a real number (got " + to_text(v) + ")", to_text(e), false};
  double d = num.to_double();
  if (!std::isfinite(d))
    throw BadConstant{"evaluates to " + fmt(d), to_text(e), true};
  return d;
}

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
  Compiler(const std::vector<GiNaC::realsymbol>& syms, bool cse) : syms_(syms), cse_(cse) {}

  /// Registers sin/cos arguments of all targets so that sin(u), cos(u) pairs fuse to sincos.
  void scan(const ex& e) {
    if (GiNaC::is_a<GiNaC::function>(e)) {
      const std::string name = GiNaC::ex_to<GiNaC::function>(e).get_name();
      if (name == "sin") sin_args_.insert(e.op(0));
      if (name == "cos") cos_args_.insert(e.op(0));
    }
    for (std::size_t i = 0; i < e.nops(); ++i) scan(e.op(i));
  }

  Operand compile(const ex& e) {
    if (cse_) {
      auto it = memo_.find(e);
      if (it != memo_.end()) return it->second;
    }
    Operand r = compile_uncached(e);
    if (cse_) memo_.emplace(e, r);
    return r;
  }

  std::size_t size() const { return code_.size(); }
  std::uint32_t num_values() const { return next_value_; }
  const std::vector<SsaInstr>& code() const { return code_; }
  const std::vector<std::pair<std::uint32_t, int>>& loads() const { return loads_; }

 private:
  std::uint32_t new_value() { return next_value_++; }

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
        if (has_symbol(e.op(i)))
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
      if (!has_symbol(term)) {
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
      if (!has_symbol(f)) {
        constant *= f;
        continue;
      }
      if (GiNaC::is_a<GiNaC::power>(f) && GiNaC::is_a<GiNaC::numeric>(f.op(1)) &&
          !has_symbol(f.op(1))) {
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
    if (!has_symbol(p)) {
      double pv = constant_value(p);
      Operand base = compile(b);
      if (base.is_const) return Operand::constant(std::pow(base.c, pv));
      return pow_numeric(base, pv);
    }
    Operand expo = compile(p);
    if (!has_symbol(b)) {  // c^u = exp(u log c)
      double bv = constant_value(b);
      if (bv > 0) return function(Op::Exp, scale(expo, std::log(bv)));
      return emit(Op::Pow, reg(Operand::constant(bv)), expo.v);
    }
    Operand base = compile(b);
    return emit(Op::Pow, reg(base), reg(expo));
  }

  Operand compile_function(const ex& e) {
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
    if (!has_symbol(e)) return Operand::constant(constant_value(e));
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
  std::vector<SsaInstr> code_;
  std::vector<std::pair<std::uint32_t, int>> loads_;
  std::uint32_t next_value_ = 0;
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

std::mutex& ginac_mutex() {
  static std::mutex m;
  return m;
}

}  // namespace

// ------------------------------------------------------------------------------------------
// Expression
// ------------------------------------------------------------------------------------------

Expression::Expression(const std::string& text, const std::vector<std::string>& variables,
                       const std::map<std::string, double>& parameters, int derivative_order)
    : Expression(text, variables, parameters, ExpressionOptions{derivative_order, true}) {}

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

  FrontEnd fe(text, impl->variables, parameters, syms);
  std::string ginac_text = fe.parse();

  // Locates the innermost source sub-expression for which `bad` holds.
  auto locate = [&](auto&& bad) -> const Node* {
    for (const Node& node : fe.nodes) {
      try {
        GiNaC::parser p(fe.symtab, true);
        if (bad(p(node.ginac_text))) return &node;
      } catch (...) {
        return &node;
      }
    }
    return nullptr;
  };
  auto fail_node = [&](const Node* node, const std::string& what, const std::string& hint) {
    if (node)
      fail_at(text, node->pos, node->end - node->pos,
              what + " in '" + text.substr(node->pos, node->end - node->pos) + "'", hint);
    fail_at(text, std::string::npos, 0, what, hint);
  };
  const std::string param_hint =
      fe.used_parameters.empty()
          ? std::string("check the constants in the expression")
          : [&] {
              std::string s = "check the parameter values (";
              bool first = true;
              for (const auto& [name, v] : fe.used_parameters) {
                s += (first ? "" : ", ") + name + " = " + fmt(v);
                first = false;
              }
              return s + ")";
            }();

  ex value;
  try {
    GiNaC::parser p(fe.symtab, true);
    value = p(ginac_text);
  } catch (const GiNaC::parse_error& err) {
    fail_at(text, std::string::npos, 0,
            std::string("GiNaC could not parse the expression (") + err.what() + ")",
            "please report this: the front end accepted the syntax");
  } catch (const std::exception& err) {
    std::string msg = err.what();
    const Node* node = locate([](const ex&) { return false; });
    if (msg.find("division by zero") != std::string::npos)
      fail_node(node, "division by zero: a constant sub-expression is infinite", param_hint);
    fail_node(node, "a constant sub-expression cannot be evaluated (" + msg + ")", param_hint);
  }

  // Derivatives.
  std::vector<ex> grad(n, ex(0));
  std::vector<ex> hess(static_cast<std::size_t>(n) * n, ex(0));
  for (int i = 0; i < n; ++i)
    if (value.has(syms[i])) impl->used.push_back(i);
  try {
    if (derivative_order >= 1)
      for (int i : impl->used) grad[i] = value.diff(syms[i]);
    if (derivative_order >= 2)
      for (int i : impl->used)
        for (int j : impl->used)
          if (j >= i) hess[i * n + j] = hess[j * n + i] = grad[i].diff(syms[j]);
  } catch (const std::exception& err) {
    fail_at(text, std::string::npos, 0,
            std::string("differentiation failed (") + err.what() + ")", param_hint);
  }

  // Hessian entries for detecting a constant Hessian when it was not requested.
  const bool try_quadratic = options.specialize && derivative_order >= 1 &&
                             static_cast<int>(impl->used.size()) <= kMaxQuadratic;
  bool hessian_constant = try_quadratic;
  if (try_quadratic) {
    try {
      for (int i : impl->used)
        for (int j : impl->used) {
          if (j < i) continue;
          ex h = derivative_order >= 2 ? hess[i * n + j] : grad[i].diff(syms[j]);
          if (has_symbol(h)) hessian_constant = false;
          if (derivative_order < 2) hess[i * n + j] = hess[j * n + i] = h;
        }
    } catch (const std::exception&) {
      hessian_constant = false;
    }
  }

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
      for (int i : impl->used) out.grad.push_back({i, comp.compile(grad[i])});
    out.stage_end[1] = comp.size();
    if (derivative_order >= 2)
      for (int i : impl->used)
        for (int j : impl->used)
          if (j >= i) out.hess.push_back({i * n + j, comp.compile(hess[i * n + j])});
    out.stage_end[2] = comp.size();
    out.code = comp.code();
    out.loads = comp.loads();
    out.num_values = comp.num_values();
  };
  try {
    Compiler comp(syms, true);
    compile_all(comp, prog);
    // The same targets without CSE, for diagnostics (tape_size_without_cse).
    Compiler plain(syms, false);
    compile_all(plain, plain_prog);

    if (hessian_constant) {
      const int m = static_cast<int>(impl->used.size());
      for (int k = 0; k < m; ++k)
        for (int l = 0; l < m; ++l)
          impl->quad.A[k * m + l] = constant_value(hess[impl->used[k] * n + impl->used[l]]);
    }
  } catch (const BadConstant& bc) {
    auto is_bad = [](const ex& e) {
      if (has_symbol(e)) return false;
      try {
        constant_value(e);
        return false;
      } catch (const BadConstant&) {
        return true;
      }
    };
    const Node* node = locate(is_bad);
    std::string what = bc.infinite
                           ? "a constant sub-expression is infinite ('" + bc.constant + "' " +
                                 bc.what + ")"
                           : "non-numeric leftover: a constant sub-expression " + bc.what;
    fail_node(node, what, param_hint);
  }

  // Texts.
  impl->text = to_text(value);
  if (derivative_order >= 1)
    for (int i = 0; i < n; ++i) impl->grad_text.push_back(to_text(grad[i]));
  if (derivative_order >= 2)
    for (const ex& h : hess) impl->hess_text.push_back(to_text(h));

  fuse(plain_prog);
  impl->tape_without_cse = static_cast<int>(plain_prog.code.size());
  fuse(prog);
  lower(prog, *impl);
  if (hessian_constant) setup_quadratic(*impl);
  kernel_ = impl->select_kernel();
  order_ = impl->order;
  raw_ = impl.get();
  impl_ = std::move(impl);
}

int Expression::num_variables() const { return impl_->n; }
const std::vector<std::string>& Expression::variables() const { return impl_->variables; }
std::vector<int> Expression::used_variables() const { return impl_->used; }
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
