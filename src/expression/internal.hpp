#pragma once
// Private to the expression engine (src/expression/*.cpp): types shared by its stages.
//   parser.cpp      front end: lexer and recursive-descent parser (names, precedence, errors)
//   lowering.cpp    GiNaC: expression building, parameter substitution, differentiation,
//                   error location
//   compiler.cpp    tape compiler, front end: GiNaC → SSA (ssa.hpp) with CSE and constant
//                   folding
//   tape_backend.cpp tape compiler, back end: fusion, register allocation, output layout,
//                   quadratic kernel set-up
//   interpreter.cpp interpreter loop and closed-form kernels
//   expression.cpp  the public Expression API
#include "refdyn/expression/expression.hpp"

#include <ginac/ginac.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace refdyn {
namespace expr_detail {

// ------------------------------------------------------------------------------------------
// Tape
// ------------------------------------------------------------------------------------------
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
  Sign,  // u >= 0 ? 1 : -1 (the derivative of abs, right-sided at 0)
  // Piecewise selection.
  CmpLt,   // a < b ? 1 : 0
  CmpLe,   // a <= b ? 1 : 0
  Select,  // a != 0 ? b : e, the third register e stored in the bits of d (select_else)
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
    {"abs", 1, 2},    {"sign", 1, 2},   {"cmplt", 2, 0},    {"cmple", 2, 0},
    {"select", 2, 0}, {"loadx", 0, 0}, {"value_out", 1, 0}, {"value_out_c", 0, 1},
    {"grad_out", 0, 0}, {"grad_out", 0, 0}, {"grad_out", 0, 0}, {"grad_out", 0, 0},
    {"grad_out", 0, 0}, {"hess_out", 0, 0}, {"hess_out", 0, 0}, {"hess_out", 0, 0},
    {"hess_out", 0, 0}, {"hess_out", 0, 0}, {"end", 0, 0},
}};

inline const OpInfo& info(Op op) { return kOpInfo[static_cast<int>(op)]; }
inline bool is_function(Op op) { return op >= Op::Sqrt && op <= Op::Sign; }
/// Select's third input (a register or SSA value) travels in the bits of the immediate d.
inline double select_else_bits(std::uint32_t e) {
  return std::bit_cast<double>(static_cast<std::uint64_t>(e));
}
inline std::uint32_t select_else(double d) {
  return static_cast<std::uint32_t>(std::bit_cast<std::uint64_t>(d));
}

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
double apply(Op op, double a, double b, double c, double d);

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

}  // namespace expr_detail

struct Expression::Impl {
  std::string source;
  std::vector<std::string> variables;
  int order = 2;
  int n = 0;
  std::vector<int> used;
  std::vector<int> referenced;  // variables written in the text (superset of used)

  // The program: loads, value stage, value store, exit if no derivatives wanted, gradient
  // stage, gradient stores (skipped without grad), exit if no Hessian wanted, Hessian stage,
  // Hessian stores, End.
  std::vector<expr_detail::Instr> code;
  int instructions = 0;  // arithmetic instructions (the tape proper: no loads/stores/control)
  int registers = 0;
  int tape_without_cse = 0;

  std::vector<expr_detail::OutputSlot> slots;      // loads and register outputs (see OutBlock)
  std::vector<expr_detail::ConstSlot> consts;      // constant outputs written by GradOut/HessOut
  std::vector<expr_detail::OutBlock> blocks;       // [gradient, Hessian]
  std::vector<std::uint32_t> sources; // dense output sources
  std::vector<double> pool;           // constants of dense outputs
  expr_detail::ProgramView view;                   // pointers into the vectors above (set once built)
  std::vector<expr_detail::ConstSlot> grad_const;  // constant (incl. zero) gradient entries
  std::vector<expr_detail::ConstSlot> hess_const;  // constant (incl. zero) Hessian entries

  expr_detail::Quadratic quad;

  std::string text;
  std::vector<std::string> grad_text;
  std::vector<std::string> hess_text;  // n*n, filled when order >= 2

  /// The tape interpreter with caller-provided registers r (size >= registers).
  void run_tape_program(const double* x, double* r, double& value, double* grad,
                        double* hess) const;
  /// The kernel for this expression.
  Expression::Kernel select_kernel() const;

  /// ExpressionOptions::extra_derivative_order: the derivative's value-only program and kernel.
  std::shared_ptr<const Impl> extra;
  Expression::Kernel extra_kernel = nullptr;
};

}  // namespace refdyn

namespace refdyn {
namespace expr_detail {

// ------------------------------------------------------------------------------------------
// Front end (parser.cpp)
// ------------------------------------------------------------------------------------------
std::string strip_spaces(const std::string& s);
bool is_ident_start(char ch);
bool is_ident_char(char ch);

/// Throws Error: "expression "TEXT": WHAT at column C\n    TEXT\n    ^^^\n(hint: HINT)"
/// (pos == npos: no location).
[[noreturn]] void fail_at(const std::string& text, std::size_t pos, std::size_t len,
                          const std::string& what, const std::string& hint);

/// Functions of the expression language (see expression.hpp).
enum class Fn : std::uint8_t {
  Sin, Cos, Tan, Asin, Acos, Atan, Atan2, Sinh, Cosh, Tanh, Asinh, Acosh, Atanh, Exp, Log, Sqrt,
  Abs, Pow, Min, Max, Step, Clamp, If
};
/// The comparison of an if(lhs CMP rhs, a, b).
enum class Cmp : std::uint8_t { Lt, Le, Gt, Ge };

enum class AstKind : std::uint8_t {
  Number,     // literal `text`
  Variable,   // variable `index`
  Parameter,  // parameter `text` with value `value`
  Pi,
  E,
  Sum,      // kids with flags: 0 add, 1 subtract
  Product,  // kids with flags: 0 multiply, 1 divide
  Neg,      // -kid
  Power,    // kid0 ^ kid1
  Call      // fn(kids...); If: kids lhs, rhs, a, b and `cmp`
};

/// One node of the syntax tree. Nodes are stored children first (post-order), so a single
/// forward pass over ParseResult::nodes visits every child before its parent: nothing after the
/// parser recurses over the tree's depth except GiNaC, which only sees trees whose depth the
/// parser has bounded (ExpressionOptions::max_depth).
struct AstNode {
  explicit AstNode(AstKind k) : kind(k) {}
  AstKind kind;
  Fn fn = Fn::Sin;
  Cmp cmp = Cmp::Lt;
  bool located = false;          // compound node: a candidate for error locations
  std::uint32_t pos = 0, end = 0;  // source span [pos, end)
  std::uint32_t first = 0, count = 0;  // children: ParseResult::kids[first, first + count)
  int index = -1;                // variable index
  double value = 0.0;            // parameter value
  std::string text;              // number literal or parameter name
};

/// What the front end hands to the lowering.
struct ParseResult {
  std::vector<AstNode> nodes;  // children before parents; the root is the last node
  std::vector<std::uint32_t> kids;
  std::vector<std::uint8_t> flags;  // per kid: Sum 1 = subtract, Product 1 = divide
  std::map<std::string, double> used_parameters;
};

/// Parses `text` over the (whitespace-stripped) variables. Checks the limits of `opt`
/// (max_length before anything else, max_depth while parsing, so recursion is bounded).
/// Throws Error with a location for every syntax or name error.
ParseResult parse_front_end(const std::string& text, const std::vector<std::string>& variables,
                            const std::map<std::string, double>& parameters,
                            const ExpressionOptions& opt);

/// The user-visible function list ("sin, cos, ..."), as printed in error hints.
std::string function_list();

// ------------------------------------------------------------------------------------------
// Lowering to GiNaC, derivatives, constant checks (lowering.cpp)
// ------------------------------------------------------------------------------------------
bool has_symbol(const GiNaC::ex& e);
std::string to_text(const GiNaC::ex& e);  // GiNaC's printout (messages about constants)
/// e in refdyn's expression syntax, parsed back to the same function (the piecewise ones
/// included), with GiNaC's per-process choices of operand order and of a sum factor's sign
/// undone (source_text.cpp; what stays: Expression::text()).
std::string source_text(const GiNaC::ex& e);

/// Thrown by the compiler for a constant that is not a finite real number; the constructor
/// turns it into an Error with a location (fail_bad_constant).
struct BadConstant {
  std::string what;      // description
  std::string constant;  // GiNaC text of the constant
  bool infinite;
};

/// The double value of a constant expression; throws BadConstant if it is not a finite real.
double constant_value(const GiNaC::ex& e);

/// The expression and its exact derivatives.
struct Symbolic {
  GiNaC::ex value;
  std::vector<GiNaC::ex> grad;  // n, 0 for unused variables (filled when order >= 1)
  std::vector<GiNaC::ex> hess;  // n*n, symmetric (filled when order >= 2 or hessian_constant)
  std::vector<int> used;        // variables the value depends on, ascending
  bool hessian_constant = false;  // quadratic kernel candidate (see ExpressionOptions)
};

/// Builds the GiNaC expression from the syntax tree (one forward pass, no recursion over the
/// tree) and differentiates it.
Symbolic lower_symbolic(const std::string& text, const ParseResult& fe,
                        const std::vector<GiNaC::realsymbol>& syms, const ExpressionOptions& opt);

/// Turns a BadConstant from the compiler into an Error that points at the innermost source
/// sub-expression with a bad constant value.
[[noreturn]] void fail_bad_constant(const std::string& text, const ParseResult& fe,
                                    const std::vector<GiNaC::realsymbol>& syms,
                                    const BadConstant& bc);

/// The piecewise functions the lowering introduces (GiNaC functions with exact one-sided
/// derivatives; see expression.hpp for the conventions):
///   rd_abs(u)             |u|, d/du = rd_sgn(u)
///   rd_sgn(u)             u >= 0 ? 1 : -1 (derivative 0)
///   rd_if_lt(x, y, a, b)  x <  y ? a : b  (derivatives taken inside the branches)
///   rd_if_le(x, y, a, b)  x <= y ? a : b
/// Their GiNaC serials, for the compiler.
unsigned serial_abs();
unsigned serial_sgn();
unsigned serial_if_lt();
unsigned serial_if_le();
///   rd_min(a, b)          a <= b ? a : b, derivative rd_if_le(a, b, da, db)
///   rd_max(a, b)          b <= a ? a : b, derivative rd_if_le(b, a, da, db)
///   rd_step(u)            u >= 0 ? 1 : 0, derivative 0
///   rd_clamp(x, lo, hi)   x < lo ? lo : (hi < x ? hi : x)
unsigned serial_min();
unsigned serial_max();
unsigned serial_step();
unsigned serial_clamp();
/// True if e contains one of the piecewise functions (no quadratic kernel then).
bool has_piecewise(const GiNaC::ex& e);

// ------------------------------------------------------------------------------------------
// Tape compiler (compiler.cpp, tape_backend.cpp)
// ------------------------------------------------------------------------------------------
/// Compiles value (+ gradient + Hessian, per impl.order) into impl's program: SSA with CSE and
/// constant folding, fusion, register allocation, output layout, quadratic kernel set-up.
/// Throws BadConstant for a constant that is not a finite real number.
void compile_tape(const Symbolic& s, const std::vector<GiNaC::realsymbol>& syms,
                  Expression::Impl& impl);

/// GiNaC is not thread-safe: every use of it in the engine holds this mutex.
std::mutex& ginac_mutex();

/// The value of `text` as a GiNaC expression in `syms` (one per variable, same order; no
/// parameters: names meant as parameters are passed as variables), for the code generator
/// (src/symbolic). Same syntax, limits and errors as Expression; the caller holds ginac_mutex().
GiNaC::ex symbolic_value(const std::string& text, const std::vector<std::string>& variables,
                         const std::vector<GiNaC::realsymbol>& syms);

}  // namespace expr_detail
}  // namespace refdyn
