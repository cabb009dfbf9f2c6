#pragma once
/// Scenario files: a mechanism, its task constraints, forces, initial state, integrator,
/// controller and experiments, described in YAML (docs/scenario.md documents every key).
/// Errors name the file, the line and the key, e.g.
///   arm.yaml:12: model.dh.joints[1].mass: expected a number >= 0, got -3

#include "refdyn/constraints.hpp"
#include "refdyn/control.hpp"
#include "refdyn/force_elements.hpp"
#include "refdyn/integrators.hpp"
#include "refdyn/model.hpp"
#include "refdyn/reference_dynamics.hpp"

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace refdyn::io {

struct ControllerSpec {
  std::string type = "computed_torque_pd";  ///< or "pd_gravity"
  Eigen::VectorXd delta;                    ///< computed_torque_pd gains [1/s]
  Eigen::VectorXd kp, kd;                   ///< pd_gravity gains
};

struct Experiment {
  std::string name;
  Eigen::VectorXd q0, qd0;                  ///< plant initial state
  ForceSet plant_forces;                    ///< the plant's own force elements
  ControllerSpec controller;                ///< the experiment's own, else the top-level one
};

/// A loaded, validated scenario. Not movable: ReferenceDynamics objects refer to its members.
struct Scenario {
  Scenario() = default;
  Scenario(const Scenario&) = delete;
  Scenario& operator=(const Scenario&) = delete;

  std::string file;
  std::string name;
  std::map<std::string, double> parameters;
  ModelDescription description;
  Model model;
  ForceSet forces;
  ConstraintSet constraints;
  ReferenceDynamicsOptions options;
  bool automatic_independent = false;       ///< partition: auto
  Eigen::VectorXd q0, qd0;                  ///< reference initial state (as written)
  bool project_initial = false;             ///< make (q0, qd0) consistent by Newton projection
  double initial_tolerance = 1e-8;          ///< accepted initial constraint residual
  Eigen::VectorXd initial_dq, initial_dqd;  ///< correction applied by the projection (zeros if none)
  IntegratorOptions integrator;
  double residual_from = 0.0;               ///< report max residual over t >= this
  ControllerSpec controller;
  Eigen::VectorXd effort_limit;             ///< closed-loop saturation (empty: none)
  std::vector<std::unique_ptr<Experiment>> experiments;
  std::vector<std::string> report_points;   ///< points whose positions go into the CSV files
};

/// Loads and validates a scenario file. Throws refdyn::Error "FILE:LINE: KEY: message".
std::unique_ptr<Scenario> load_scenario(const std::string& path);
/// Same from text (`source_name` is used in messages and to resolve relative paths).
std::unique_ptr<Scenario> parse_scenario(const std::string& yaml, const std::string& source_name);

}  // namespace refdyn::io
