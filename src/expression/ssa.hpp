#pragma once
// Private to the tape compiler (compiler.cpp: GiNaC → SSA; tape_backend.cpp: SSA → the program
// the interpreter runs). The SSA form between the two.
#include "internal.hpp"

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

namespace refdyn {
namespace expr_detail {

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

/// Peephole fusion of common instruction pairs when the intermediate has no other use
/// (tape_backend.cpp).
void fuse(SsaProgram& prog);
/// Liveness, linear-scan register allocation and output layout into impl's program
/// (tape_backend.cpp).
void lower(const SsaProgram& prog, Expression::Impl& impl);
/// The closed-form quadratic kernel, when impl's Hessian is constant (tape_backend.cpp).
void setup_quadratic(Expression::Impl& impl);

}  // namespace expr_detail
}  // namespace refdyn
