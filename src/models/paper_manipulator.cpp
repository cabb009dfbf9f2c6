#include "refdyn/models/paper_manipulator.hpp"

#include <numbers>

namespace refdyn::models {

ModelDescription paper_manipulator_description() {
  const double deg = std::numbers::pi / 180.0;
  auto diag = [](double a, double b, double c) { return Vec3(a, b, c).asDiagonal().toDenseMatrix(); };
  std::vector<DHRow> rows(3);
  rows[0] = {JointType::Revolute, 0.0, kPaperH1, 0.0, -90 * deg,
             {20.0, Vec3(0, 0.3, 0), diag(0.6125, 0.025, 0.6125)}, {}, "psi1"};
  rows[1] = {JointType::Revolute, 0.0, 0.0, 0.0, -90 * deg,
             {8.0, Vec3(0, 0, 0.1), diag(8 * 0.1648 / 12, 8 * 0.1648 / 12, 0.0064)}, {}, "psi2"};
  rows[2] = {JointType::Prismatic, 0.0, 0.0, 0.0, 0.0,
             {3.0, Vec3(0, 0, -0.4), diag(0.1603, 0.1603, 0.0006)}, {}, "z3"};
  ModelDescription d = from_dh(rows, DHConvention::Standard, "paper_manipulator");
  d.links[0].name = "column";
  d.links[1].name = "arm";
  d.links[2].name = "slider";
  d.gravity = Vec3(0, 0, -9.81);
  d.add_point("E", "slider", Vec3::Zero());
  return d;
}

Model paper_manipulator() { return build_model(paper_manipulator_description()); }

}  // namespace refdyn::models
