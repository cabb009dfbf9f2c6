// Expression engine, stage 3 (back end of the tape compiler): peephole fusion of the SSA
// program, liveness and linear-scan register allocation, the layout of the outputs, and the
// set-up of the closed-form quadratic kernel. The front end (GiNaC → SSA) is compiler.cpp.
#include "ssa.hpp"

#include <algorithm>
#include <functional>
#include <initializer_list>
#include <queue>

namespace refdyn {
namespace expr_detail {

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

namespace {

/// Where each SSA value is needed last, and whether it is needed at all. Outputs of stage s are
/// read right after it, i.e. they live until position stage_end[s] (the next stage's first
/// instruction may reuse them).
struct Liveness {
  std::vector<std::size_t> last_use;
  std::vector<bool> used_any;
};

Liveness liveness(const SsaProgram& prog) {
  const std::vector<SsaInstr>& code = prog.code;
  Liveness live{std::vector<std::size_t>(prog.num_values, 0), std::vector<bool>(prog.num_values, false)};
  auto use = [&](std::uint32_t v, std::size_t pos) {
    live.used_any[v] = true;
    live.last_use[v] = std::max(live.last_use[v], pos);
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
  return live;
}

/// The register file of the linear scan: free registers are reused lowest first (keeps the
/// register file compact and deterministic), else a new one is taken.
class Registers {
 public:
  std::uint32_t alloc() {
    if (free_.empty()) return count_++;
    std::uint32_t r = free_.top();
    free_.pop();
    return r;
  }
  void release(std::uint32_t r) { free_.push(r); }
  std::uint32_t count() const { return count_; }

 private:
  std::priority_queue<std::uint32_t, std::vector<std::uint32_t>, std::greater<>> free_;
  std::uint32_t count_ = 0;
};

/// Output entries (gradient, or the upper triangle of the Hessian mirrored): registers or
/// constants (structural zeros included).
void output_entries(const std::vector<std::pair<int, Operand>>& entries, bool hessian, int n,
                    const std::vector<std::uint32_t>& phys, std::vector<ConstSlot>& consts,
                    std::vector<OutputSlot>& regs) {
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
}

/// One output block of impl: dense (a source per entry) when small, else zero-fill when there
/// are many zeros, then constants and registers. Returns its index in impl.blocks.
std::uint32_t make_block(Expression::Impl& impl, const std::vector<ConstSlot>& consts,
                         const std::vector<OutputSlot>& regs, std::size_t size) {
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
}

/// Small dense outputs get an op of their own (unrolled, no block lookup).
void specialise_output(const Expression::Impl& impl, Instr& ins, Op first,
                       std::initializer_list<std::uint32_t> sizes) {
  const OutBlock& bl = impl.blocks[ins.a];
  int k = 0;
  for (std::uint32_t size : sizes) {
    if (bl.dense_n == size) {
      ins.op = static_cast<Op>(static_cast<int>(first) + k);
      ins.b = bl.d_off;
    }
    ++k;
  }
}

/// The output instruction of stage `stage` (0 value, 1 gradient, 2 Hessian, then End), emitted
/// once the stage's instructions have their registers.
void close_stage(const SsaProgram& prog, std::size_t stage, const std::vector<std::uint32_t>& phys,
                 Expression::Impl& impl) {
  std::vector<Instr>& out = impl.code;
  const int n = prog.n;
  if (stage == 0) {
    if (prog.value.is_const)
      out.push_back({Op::ValueOutC, 0, 0, 0, prog.value.c, 0.0});
    else
      out.push_back({Op::ValueOut, 0, phys[prog.value.v], 0, 0.0, 0.0});
  } else if (stage == 1 && impl.order >= 1) {
    std::vector<OutputSlot> regs;
    output_entries(prog.grad, false, n, phys, impl.grad_const, regs);
    out.push_back({Op::GradOut, 0, make_block(impl, impl.grad_const, regs, n), 0, 0.0, 0.0});
    specialise_output(impl, out.back(), Op::GradOut1, {1, 2, 3, 4});
  } else if (stage == 2 && impl.order >= 2) {
    std::vector<OutputSlot> regs;
    output_entries(prog.hess, true, n, phys, impl.hess_const, regs);
    out.push_back({Op::HessOut, 0, make_block(impl, impl.hess_const, regs, static_cast<std::size_t>(n) * n), 0,
                   0.0, 0.0});
    specialise_output(impl, out.back(), Op::HessOut1, {1, 4, 9, 16});
  }
  if (stage == 2) out.push_back({Op::End, 0, 0, 0, 0.0, 0.0});
}

}  // namespace

/// Liveness, linear-scan register allocation and layout (stages separated by End markers).
void lower(const SsaProgram& prog, Expression::Impl& impl) {
  const std::vector<SsaInstr>& code = prog.code;
  const std::uint32_t num_values = prog.num_values;
  const Liveness live = liveness(prog);
  std::vector<std::uint32_t> phys(num_values, 0);
  Registers file;
  std::vector<std::vector<std::uint32_t>> dying(code.size() + 1);
  for (std::uint32_t v = 0; v < num_values; ++v)
    if (live.used_any[v]) dying[std::min(live.last_use[v], code.size())].push_back(v);
  std::vector<Instr>& out = impl.code;
  out.clear();
  impl.slots.clear();
  for (const auto& [v, var] : prog.loads) {
    phys[v] = file.alloc();
    impl.slots.push_back({static_cast<std::uint32_t>(var), phys[v]});
  }
  if (!prog.loads.empty())
    out.push_back({Op::LoadX, 0, 0, static_cast<std::uint32_t>(impl.slots.size()), 0.0, 0.0});

  std::size_t stage = 0;
  auto close_stages = [&](std::size_t i) {
    while (stage < 3 && prog.stage_end[stage] == i) close_stage(prog, stage++, phys, impl);
  };
  for (std::size_t i = 0; i < code.size(); ++i) {
    close_stages(i);
    const SsaInstr& in = code[i];
    // Inputs dying here (and outputs of the previous stage, already stored) may be reused by
    // this instruction's outputs: the interpreter reads inputs before writing outputs.
    for (std::uint32_t v : dying[i]) file.release(phys[v]);
    Instr ins{in.op, 0, 0, 0, in.c, in.d};
    int inputs = info(in.op).inputs;
    if (inputs >= 1) ins.a = phys[in.a];
    if (inputs >= 2) ins.b = phys[in.b];
    if (in.op == Op::Select) ins.d = select_else_bits(phys[select_else(in.d)]);
    phys[in.dst] = file.alloc();
    ins.dst = phys[in.dst];
    if (in.op == Op::SinCos) {
      phys[in.b] = file.alloc();
      ins.b = phys[in.b];
      if (!live.used_any[in.b]) file.release(phys[in.b]);
    }
    if (!live.used_any[in.dst]) file.release(phys[in.dst]);
    out.push_back(ins);
  }
  close_stages(code.size());
  impl.view = {impl.code.data(),   impl.slots.data(),   impl.consts.data(),
               impl.blocks.data(), impl.sources.data(), impl.pool.data()};
  impl.instructions = static_cast<int>(code.size());
  impl.registers = static_cast<int>(std::max<std::uint32_t>(file.count(), 1));
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

}  // namespace expr_detail
}  // namespace refdyn
