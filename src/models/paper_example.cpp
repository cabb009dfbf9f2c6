#include "refdyn/models/paper_example.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/models/paper_manipulator.hpp"

#include <cmath>
#include <numbers>

namespace refdyn::models {

namespace {
Model build_paper_model(const PaperExampleParams& p) {
  ModelDescription d = paper_manipulator_description();
  if (!p.limits.empty()) {
    if (p.limits.size() != d.links.size())
      throw Error(expected_got("paper example limits", std::to_string(d.links.size()) + " entries (one per joint)",
                               std::to_string(p.limits.size())));
    for (size_t i = 0; i < d.links.size(); ++i) d.links[i].limits = p.limits[i];
  }
  return build_model(d);
}
}  // namespace

PaperExample::PaperExample(const PaperExampleParams& p) : params(p), model(build_paper_model(p)) {
  if (p.with_drive) {
    drive = std::make_shared<FlexibleDrive>(model, "psi1", p.drive,
                                            cycloidal(p.drive_rise, p.drive_duration));
    forces.add(drive);
  }
  if (p.with_friction) {
    forces.add(std::make_shared<LuGreFriction>(model, "psi1", p.lugre_rot));
    forces.add(std::make_shared<LuGreFriction>(model, "psi2", p.lugre_rot));
    forces.add(std::make_shared<LuGreFriction>(model, "z3", p.lugre_lin));
  }
  const double z0 = kPaperH1 + 0.5 * std::sin(std::numbers::pi / 4);
  z_a = raised_cosine(z0, p.z_amplitude, p.z_period);
  ConstraintPtr ellipse, height;
  if (p.expression_constraints) {
    ellipse = expression_constraint(model, "ellipse", "(x(E)/a)^2 + (y(E)/b)^2 - 1", false,
                                    {{"a", p.ellipse_a}, {"b", p.ellipse_b}});
    height = expression_constraint(model, "height", "z(E) - (z0 + dz*(1 - cos(2*pi*t/Tz))/2)", false,
                                   {{"z0", z0}, {"dz", p.z_amplitude}, {"Tz", p.z_period}});
  } else {
    NewConstraint e = point_on_surface(model, "E", elliptic_cylinder(p.ellipse_a, p.ellipse_b));
    e->name = "ellipse";
    NewConstraint h = point_coordinate(model, "E", 2, z_a);
    h->name = "height";
    ellipse = e;
    height = h;
  }
  constraints.add(ellipse);
  constraints.add(height);
}

ReferenceDynamicsOptions PaperExample::options() const {
  ReferenceDynamicsOptions o;
  o.alpha = params.alpha;
  o.beta = params.beta;
  o.independent = {"psi1"};
  o.solver = ReferenceSolver::Projection;  // the paper's method (also what Automatic picks at 3 DOF)
  return o;
}

Eigen::VectorXd PaperExample::q0() const {
  Eigen::VectorXd q(3);
  q << 0.0, 1.5 * std::numbers::pi - params.elevation0, params.z3_0;
  return q;
}

IntegratorOptions PaperExample::integrator() const {
  IntegratorOptions o;
  o.method = IntegratorMethod::RK4;
  o.t0 = 0.0;
  o.t1 = params.t1;
  o.step = params.step;
  return o;
}

}  // namespace refdyn::models
