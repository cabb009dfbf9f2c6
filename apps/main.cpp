// refdyn command line. Catches refdyn::Error once, prints one line, exits non-zero.
#include "paper_study_output.hpp"
#include "refdyn/error.hpp"
#include "refdyn/models/paper_manipulator.hpp"
#include "refdyn/recursive_dynamics.hpp"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <numbers>

namespace {

[[maybe_unused]] int print_model_summary() {
  using namespace refdyn;
  const Model model = models::paper_manipulator();
  Data data(model);
  Eigen::VectorXd q(3), qd = Eigen::VectorXd::Zero(3);
  q << 0.0, 225.0 * std::numbers::pi / 180.0, 0.5;
  std::cout << model.summary();
  const Eigen::IOFormat f(8, 0, "  ", "\n", "    [", "]");
  std::cout << "initial state q = [0, 225 deg, 0.5 m], qd = 0\n";
  std::cout << "M(q0) =\n" << mass_matrix(model, data, q).format(f) << "\n";
  std::cout << "c(q0, qd0) + g(q0) =\n" << bias_forces(model, data, q, qd).transpose().format(f) << "\n";
  std::cout << "g(q0) =\n" << gravity_forces(model, data, q).transpose().format(f) << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"refdyn: task-based motion planning from computationally generated reference dynamics"};
  app.require_subcommand(1);
  std::string out_dir = "results";
  auto* paper = app.add_subcommand("paper", "Run the paper's three-link manipulator study");
  paper->add_option("-o,--output", out_dir, "Output folder")->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    if (*paper) return refdyn::app::run_paper_command(out_dir, false);
  } catch (const refdyn::Error& e) {
    std::fprintf(stderr, "refdyn: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "refdyn: internal error: %s\n", e.what());
    return 3;
  }
  return 0;
}
