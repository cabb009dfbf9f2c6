#pragma once
/// refdyn in one include: the public API of both libraries (refdyn::core and refdyn::io).
///   #include <refdyn/refdyn.hpp>
/// A program that wants a shorter build includes only the headers it uses (each includes what it
/// needs). Not included here: the building blocks a program does not call directly (dual numbers'
/// Eigen traits, the JSON field writers, the multibody kernels' scalar plumbing), which the
/// headers below include where they need them. Nothing under src/ may include this file
/// (tests/layers_test.py: it is the top layer below apps/).

// the mechanism: models, kinematics, dynamics
#include "refdyn/multibody/generic_dynamics.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
// the task: expressions, time laws, constraints, force elements
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/expression/expression.hpp"
#include "refdyn/expression/time_function.hpp"
#include "refdyn/expression/time_law.hpp"
#include "refdyn/forces/force_elements.hpp"
// the reference dynamics (orders ≤ 2 and 3)
#include "refdyn/reference/jerk.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
// planning, tracking, feasibility
#include "refdyn/simulate/closed_loop.hpp"
#include "refdyn/simulate/controllers.hpp"
#include "refdyn/simulate/feasibility.hpp"
#include "refdyn/simulate/integrators.hpp"
#include "refdyn/simulate/metrics.hpp"
#include "refdyn/simulate/plan.hpp"
#include "refdyn/simulate/planner.hpp"
#include "refdyn/simulate/stability.hpp"
// the paper's example
#include "refdyn/models/paper_example.hpp"
#include "refdyn/models/paper_study.hpp"
// scenarios, code generation, sensitivities
#include "refdyn/scenario/problem.hpp"
#include "refdyn/symbolic/sensitivity.hpp"
#include "refdyn/symbolic/symbolic.hpp"
// files: scenarios, URDF, results; optimization
#include "refdyn/io/check.hpp"
#include "refdyn/io/output.hpp"
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/io/urdf.hpp"
#include "refdyn/optimize/optimize.hpp"
