#pragma once
/// The paper's three-link manipulator (column ψ1, rotary arm ψ2, sliding link z3), with the
/// inertias fixed in docs/paper_example.md §1–2 (uniform cylinders) and end-effector point "E"
/// at the origin of frame 3. Standard DH table:
///   joint 1 revolute  θ=ψ1  d=0.6  a=0  α=−90°
///   joint 2 revolute  θ=ψ2  d=0    a=0  α=−90°
///   joint 3 prismatic θ=0   d=z3   a=0  α=0

#include "refdyn/multibody/model.hpp"

namespace refdyn::models {

constexpr double kPaperH1 = 0.6;  ///< height of joint 2 above the base [m]

ModelDescription paper_manipulator_description();
Model paper_manipulator();

}  // namespace refdyn::models
