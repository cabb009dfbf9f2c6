// Every public entry point rejects bad input with a refdyn::Error (never a crash or a silent
// garbage result), and the message says what was expected and what it got.
#include "refdyn/common/error.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/models/paper_manipulator.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/multibody/trace_dynamics.hpp"
#include "test_support.hpp"

#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>

using namespace refdyn;

namespace {

/// Runs fn, expecting a refdyn::Error whose message contains every one of `parts`.
::testing::AssertionResult throws_with(const std::function<void()>& fn, const std::vector<std::string>& parts) {
  try {
    fn();
  } catch (const Error& e) {
    const std::string msg = e.what();
    for (const auto& p : parts)
      if (msg.find(p) == std::string::npos)
        return ::testing::AssertionFailure() << "message \"" << msg << "\" lacks \"" << p << "\"";
    return ::testing::AssertionSuccess();
  } catch (const std::exception& e) {
    return ::testing::AssertionFailure() << "threw a non-refdyn exception: " << e.what();
  } catch (...) {
    return ::testing::AssertionFailure() << "threw something that is not a std::exception";
  }
  return ::testing::AssertionFailure() << "did not throw";
}

using V = Eigen::VectorXd;

/// One argument slot of one entry point: calls the function with `arg` in that slot and valid
/// values elsewhere.
struct Slot {
  std::string function;
  std::string argument;  // the name the message must use: "q", "qd", "qdd", "tau"
  std::function<void(const Model&, Data&, const V& arg)> call;
};

std::vector<Slot> all_slots() {
  auto ok = [](const Model& m) { return V::Constant(m.nq, 0.3); };
  std::vector<Slot> s;
  s.push_back({"forward_kinematics", "q", [](const Model& m, Data& d, const V& a) { forward_kinematics(m, d, a); }});
  s.push_back({"inverse_dynamics", "q",
               [=](const Model& m, Data& d, const V& a) { inverse_dynamics(m, d, a, ok(m), ok(m)); }});
  s.push_back({"inverse_dynamics", "qd",
               [=](const Model& m, Data& d, const V& a) { inverse_dynamics(m, d, ok(m), a, ok(m)); }});
  s.push_back({"inverse_dynamics", "qdd",
               [=](const Model& m, Data& d, const V& a) { inverse_dynamics(m, d, ok(m), ok(m), a); }});
  s.push_back({"bias_forces", "q", [=](const Model& m, Data& d, const V& a) { bias_forces(m, d, a, ok(m)); }});
  s.push_back({"bias_forces", "qd", [=](const Model& m, Data& d, const V& a) { bias_forces(m, d, ok(m), a); }});
  s.push_back({"gravity_forces", "q", [](const Model& m, Data& d, const V& a) { gravity_forces(m, d, a); }});
  s.push_back({"mass_matrix", "q", [](const Model& m, Data& d, const V& a) { mass_matrix(m, d, a); }});
  s.push_back({"forward_dynamics", "q",
               [=](const Model& m, Data& d, const V& a) { forward_dynamics(m, d, a, ok(m), ok(m)); }});
  s.push_back({"forward_dynamics", "qd",
               [=](const Model& m, Data& d, const V& a) { forward_dynamics(m, d, ok(m), a, ok(m)); }});
  s.push_back({"forward_dynamics", "tau",
               [=](const Model& m, Data& d, const V& a) { forward_dynamics(m, d, ok(m), ok(m), a); }});
  s.push_back({"kinetic_energy", "q", [=](const Model& m, Data& d, const V& a) { kinetic_energy(m, d, a, ok(m)); }});
  s.push_back({"kinetic_energy", "qd", [=](const Model& m, Data& d, const V& a) { kinetic_energy(m, d, ok(m), a); }});
  s.push_back({"potential_energy", "q", [](const Model& m, Data& d, const V& a) { potential_energy(m, d, a); }});
  s.push_back({"point_drift", "qd", [](const Model& m, Data& d, const V& a) {
                 forward_kinematics(m, d, V::Zero(m.nq));
                 point_drift(m, d, 0, a);
               }});
  s.push_back({"trace_kinematics", "q", [](const Model& m, Data& d, const V& a) { trace_kinematics(m, d, a); }});
  s.push_back({"trace_mass_matrix", "q", [](const Model& m, Data& d, const V& a) { trace_mass_matrix(m, d, a); }});
  s.push_back({"trace_coriolis", "q", [=](const Model& m, Data& d, const V& a) { trace_coriolis(m, d, a, ok(m)); }});
  s.push_back({"trace_coriolis", "qd", [=](const Model& m, Data& d, const V& a) { trace_coriolis(m, d, ok(m), a); }});
  s.push_back({"trace_gravity", "q", [](const Model& m, Data& d, const V& a) { trace_gravity(m, d, a); }});
  s.push_back({"trace_kinetic_energy", "q",
               [=](const Model& m, Data& d, const V& a) { trace_kinetic_energy(m, d, a, ok(m)); }});
  s.push_back({"trace_kinetic_energy", "qd",
               [=](const Model& m, Data& d, const V& a) { trace_kinetic_energy(m, d, ok(m), a); }});
  s.push_back({"trace_potential_energy", "q",
               [](const Model& m, Data& d, const V& a) { trace_potential_energy(m, d, a); }});
  s.push_back({"trace_point_kinematics", "q",
               [=](const Model& m, Data& d, const V& a) { trace_point_kinematics(m, d, 0, a, ok(m)); }});
  s.push_back({"trace_point_kinematics", "qd",
               [=](const Model& m, Data& d, const V& a) { trace_point_kinematics(m, d, 0, ok(m), a); }});
  return s;
}

}  // namespace

TEST(Errors, EveryEntryPointRejectsWrongSizes) {
  const Model model = models::paper_manipulator();  // nq = 3
  Data data(model);
  for (const Slot& s : all_slots()) {
    for (int bad : {0, 2, 4}) {
      const V arg = V::Constant(bad, 0.1);
      EXPECT_TRUE(throws_with([&] { s.call(model, data, arg); },
                              {s.argument, "expected", "got", "size 3", "size " + std::to_string(bad)}))
          << s.function << "(" << s.argument << " of size " << bad << ")";
    }
  }
}

TEST(Errors, EveryEntryPointRejectsNonFiniteNumbers) {
  const Model model = models::paper_manipulator();
  Data data(model);
  for (const Slot& s : all_slots()) {
    for (double bad : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                       -std::numeric_limits<double>::infinity()}) {
      for (int where : {0, 2}) {
        V arg = V::Constant(3, 0.1);
        arg[where] = bad;
        EXPECT_TRUE(throws_with([&] { s.call(model, data, arg); },
                                {s.argument + "[" + std::to_string(where) + "]", "expected", "finite", "got"}))
            << s.function << "(" << s.argument << "[" << where << "] = " << bad << ")";
      }
    }
  }
}

TEST(Errors, BadPointIndex) {
  const Model model = models::paper_manipulator();  // one point, "E"
  Data data(model);
  const V q = V::Constant(3, 0.2), qd = V::Constant(3, 0.1);
  forward_kinematics(model, data, q);
  for (int bad : {-1, 1, 42}) {
    const std::string b = std::to_string(bad);
    EXPECT_TRUE(throws_with([&] { point_position(model, data, bad); }, {"point", "expected", "got " + b}));
    EXPECT_TRUE(throws_with([&] { point_jacobian(model, data, bad); }, {"point", "expected", "got " + b}));
    EXPECT_TRUE(throws_with([&] { point_drift(model, data, bad, qd); }, {"point", "expected", "got " + b}));
    EXPECT_TRUE(throws_with([&] { trace_point_kinematics(model, data, bad, q, qd); },
                            {"point", "expected", "got " + b}));
  }
}

TEST(Errors, BadBodyIndex) {
  const Model model = models::paper_manipulator();
  Data data(model);
  forward_kinematics(model, data, V::Constant(3, 0.2));
  for (int bad : {-1, 3, 100}) {
    const std::string b = std::to_string(bad);
    EXPECT_TRUE(throws_with([&] { link_transform(model, data, bad); }, {"body", "expected", "got " + b}));
  }
}

// Runs `stmt` in a forked child (a GoogleTest death test), so that an out-of-bounds access
// fails this expectation instead of crashing the whole test executable. The child prints the
// refdyn::Error message to stderr and exits 0; anything else (no throw, a crash) fails.
#define EXPECT_REFDYN_ERROR_ISOLATED(stmt, regex)                   \
  EXPECT_EXIT(                                                      \
      {                                                             \
        try {                                                       \
          stmt;                                                     \
        } catch (const refdyn::Error& e) {                          \
          std::fprintf(stderr, "refdyn::Error: %s\n", e.what());   \
          std::fflush(stderr);                                      \
          std::_Exit(0);                                            \
        }                                                           \
        std::fprintf(stderr, "did not throw\n");                   \
        std::fflush(stderr);                                        \
        std::_Exit(1);                                              \
      },                                                            \
      ::testing::ExitedWithCode(0), regex)

TEST(ErrorsDeathTest, TraceDerivativesRejectBadIndices) {
  // trace_dT / trace_ddT index model.parent[l] and data.D[i]; out-of-range indices must throw
  // refdyn::Error, not read out of bounds. (Each call runs in its own child process.)
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const Model model = models::paper_manipulator();
  Data data(model);
  trace_kinematics(model, data, V::Constant(3, 0.2));
  for (int bad : {-1, 3, 1000}) {
    const std::string re = "expected.*got " + std::to_string(bad);
    EXPECT_REFDYN_ERROR_ISOLATED(trace_dT(model, data, bad, 0), re) << "l = " << bad;
    EXPECT_REFDYN_ERROR_ISOLATED(trace_dT(model, data, 2, bad), re) << "i = " << bad;
    EXPECT_REFDYN_ERROR_ISOLATED(trace_ddT(model, data, bad, 0, 0), re) << "l = " << bad;
    EXPECT_REFDYN_ERROR_ISOLATED(trace_ddT(model, data, 2, bad, 0), re) << "i = " << bad;
    EXPECT_REFDYN_ERROR_ISOLATED(trace_ddT(model, data, 2, 0, bad), re) << "j = " << bad;
  }
}

TEST(Errors, MisspelledNamesSuggestTheClosestOne) {
  const Model model = models::paper_manipulator();
  EXPECT_TRUE(throws_with([&] { model.body_index("colum"); }, {"link", "'colum'", "did you mean 'column'"}));
  EXPECT_TRUE(throws_with([&] { model.joint_index("psi3"); }, {"joint", "'psi3'", "did you mean"}));
  EXPECT_TRUE(throws_with([&] { model.joint_index("zz3"); }, {"joint", "'zz3'", "did you mean 'z3'"}));
  EXPECT_TRUE(throws_with([&] { model.point_index("e"); }, {"point", "'e'", "did you mean 'E'"}));
  // Nothing close: the valid names are listed.
  EXPECT_TRUE(throws_with([&] { model.body_index("gripper_finger"); }, {"column", "arm", "slider"}));
  // The correct names work.
  EXPECT_EQ(model.body_index("column"), 0);
  EXPECT_EQ(model.joint_index("psi2"), 1);
  EXPECT_EQ(model.point_index("E"), 0);
}

TEST(Errors, ErrorsAreCatchableAsStdExceptions) {
  const Model model = models::paper_manipulator();
  Data data(model);
  EXPECT_THROW(mass_matrix(model, data, V::Zero(5)), Error);
  EXPECT_THROW(mass_matrix(model, data, V::Zero(5)), std::runtime_error);
  // A valid call after a rejected one still works (the workspace was not corrupted).
  const V q = V::Constant(3, 0.4);
  Data fresh(model);
  EXPECT_TRUE(test::near(mass_matrix(model, data, q), mass_matrix(model, fresh, q), 0, 0));
}
