// Expression evaluation must not allocate: this executable replaces the global operator new
// and counts the allocations made while evaluating.
#include "refdyn/expression/expression.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <string>
#include <vector>

namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};

void* counted_alloc(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
}  // namespace

void* operator new(std::size_t size) { return counted_alloc(size); }
void* operator new[](std::size_t size) { return counted_alloc(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  try {
    return counted_alloc(size);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  try {
    return counted_alloc(size);
  } catch (...) {
    return nullptr;
  }
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace refdyn {
namespace {

/// Allocations made by `f` (run `reps` times).
template <typename F>
long allocations_during(F&& f, int reps = 100) {
  g_allocations = 0;
  g_counting = true;
  for (int i = 0; i < reps; ++i) f();
  g_counting = false;
  return g_allocations.load();
}

TEST(ExpressionAlloc, CounterWorks) {
  EXPECT_GT(allocations_during([] { std::vector<double> v(10); (void)v; }, 1), 0);
}

TEST(ExpressionAlloc, EvaluateDoesNotAllocate) {
  const double kA = 0.5 * std::cos(M_PI / 4), kB = 0.25;
  const std::vector<Expression> exprs = {
      // Quadratic kernel.
      Expression("(x(E)/a)^2 + (y(E)/b)^2 - 1", {"x(E)", "y(E)"}, {{"a", kA}, {"b", kB}}),
      // Same through the tape.
      Expression("(x(E)/a)^2 + (y(E)/b)^2 - 1", {"x(E)", "y(E)"}, {{"a", kA}, {"b", kB}},
                 ExpressionOptions{.derivative_order = 2, .specialize = false}),
      // Tape with functions.
      Expression("z(E) - (z0 + dz*(1 - cos(2*pi*t/Tz))/2)", {"z(E)", "t"},
                 {{"z0", 0.95}, {"dz", 0.1}, {"Tz", 5}}),
      Expression("exp(sin(x*y)) / (1 + cos(x)^2) + x^y + atan2(y, x) + sqrt(x)", {"x", "y"}),
      // Quadratic kernel, general layout (unused variable).
      Expression("x*y + 3*x - y^2 + 2", {"x", "unused", "y"}),
  };
  double x[3] = {0.7, 1.3, 0.4};
  double v = 0, g[3], h[9];
  for (const Expression& e : exprs) {
    SCOPED_TRACE(e.source());
    EXPECT_EQ(allocations_during([&] { e.evaluate(x, v, g, h); }), 0);
    EXPECT_EQ(allocations_during([&] { e.evaluate(x, v, g, nullptr); }), 0);
    EXPECT_EQ(allocations_during([&] { v += e.value(x); }), 0);
    ExpressionWorkspace ws(e);
    EXPECT_EQ(allocations_during([&] { e.evaluate(x, v, g, h, ws); }), 0);
  }
}

// The dual-number tape (exact Jacobians, issue 21): no allocation with a workspace, nor with
// the per-thread one once it has grown.
TEST(ExpressionAlloc, DualEvaluateDoesNotAllocate) {
  const std::vector<Expression> exprs = {
      Expression("(x/a)^2 + (y/b)^2 - 1", {"x", "y"}, {{"a", 0.4}, {"b", 0.3}}),
      Expression("exp(sin(x*y)) / (1 + cos(x)^2) + x^y + atan2(y, x) + sqrt(x)", {"x", "y"}),
  };
  JacobianScalar x[2] = {JacobianScalar::variable(0.7, 0), JacobianScalar::variable(1.3, 1)};
  JacobianScalar v, g[2], h[4];
  for (const Expression& e : exprs) {
    SCOPED_TRACE(e.source());
    ExpressionDualWorkspace ws(e);
    EXPECT_EQ(allocations_during([&] { e.evaluate(x, v, g, h, ws); }), 0);
    e.evaluate(x, v, g, h);
    EXPECT_EQ(allocations_during([&] { e.evaluate(x, v, g, h); }), 0);
  }
}

TEST(ExpressionAlloc, LargeTapesWithWorkspaceDoNotAllocate) {
  std::vector<std::string> vars;
  std::string text;
  for (int i = 0; i < 300; ++i) {
    vars.push_back("v" + std::to_string(i));
    text += (i ? " + " : "") + std::string("sin(") + vars.back() + ")*" + vars.back();
  }
  const Expression e(text, vars, {}, 1);
  ASSERT_GT(e.register_count(), Expression::kStackRegisters);
  std::vector<double> x(300, 0.5), g(300);
  double v = 0;
  ExpressionWorkspace ws(e);
  EXPECT_EQ(allocations_during([&] { e.evaluate(x.data(), v, g.data(), nullptr, ws); }), 0);
  // Without a workspace: a per-thread buffer, allocated once.
  e.evaluate(x.data(), v, g.data(), nullptr);
  EXPECT_EQ(allocations_during([&] { e.evaluate(x.data(), v, g.data(), nullptr); }), 0);
}

}  // namespace
}  // namespace refdyn
