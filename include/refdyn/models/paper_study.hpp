#pragma once
/// The paper's numerical study (sections 3 and 5; docs/paper_example.md §5–7): plan the
/// motion with the reference dynamics from 45°, then track it with computed torque + PD on the
/// unconstrained plant from the disturbed starts q(0) = [0, 270° − α0, 0.5], q̇(0) = 0 for
/// α0 ∈ {45°, 60°, 70°, 80°}, without and with (unmodelled) LuGre friction in the plant.

#include "refdyn/simulate/closed_loop.hpp"
#include "refdyn/simulate/plan.hpp"
#include "refdyn/models/paper_example.hpp"

#include <memory>
#include <string>
#include <vector>

namespace refdyn::models {

struct PaperStudyOptions {
  PaperExampleParams example;                         ///< the plan (reference from 45°)
  std::vector<double> alpha0_deg{45, 60, 70, 80};     ///< initial elevations of the plant
  std::vector<bool> plant_friction{false, true};      ///< plant without / with LuGre friction
  Eigen::Vector3d delta{40.0, 3.0, 60.0};             ///< computed-torque PD gains δ [1/s]
  Eigen::VectorXd effort_limit;                       ///< optional saturation (empty: none)
};

struct PaperStudyRun {
  std::string label;        ///< e.g. "a60_friction"
  double alpha0_deg = 45;
  bool plant_friction = false;
  ClosedLoopResult result;
};

struct PaperStudy {
  PaperStudyOptions options;
  std::unique_ptr<PaperExample> example;
  std::unique_ptr<ReferenceDynamics> rd;
  Plan plan;
  ForceSet plant_friction;  ///< the LuGre elements given to the "friction" plants
  std::vector<PaperStudyRun> runs;
};

/// Runs the whole study. Throws Error for bad options; numerical outcomes are in the summaries.
PaperStudy run_paper_study(const PaperStudyOptions& options = {});

}  // namespace refdyn::models
