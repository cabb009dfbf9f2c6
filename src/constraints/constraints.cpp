#include "refdyn/constraints/constraints.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/common/text.hpp"

#include <algorithm>
#include <cmath>

namespace refdyn {

const char* to_string(ConstraintOrigin o) { return o == ConstraintOrigin::Material ? "material" : "programmed"; }

const char* order_label(int order) {
  switch (order) {
    case 0: return "holonomic (position)";
    case 1: return "first order (velocity)";
    case 2: return "acceleration (order 2)";
    case 3: return "jerk (order 3)";
    default: return "unknown";
  }
}

double TaskGeometry::value(const std::string& k) const {
  for (const auto& [name, v] : values)
    if (name == k) return v;
  return std::nan("");
}

using JS = JacobianScalar;

void Constraint::evaluate_dual(const ConstraintInputDual&, JS*, JS*, JS*, JS*) const {
  throw Error("constraint '" + name + "' (" + describe() +
              ") has no exact derivatives: its kind does not implement evaluate_dual (hint: an implicit "
              "integrator's exact Jacobian needs it; use an explicit integrator, or write the constraint as an "
              "expression constraint)");
}

void ConstraintSet::add(ConstraintPtr c) {
  if (!c) throw Error("ConstraintSet::add: expected a constraint, got none");
  for (const auto& e : constraints_)
    if (e->name == c->name)
      throw Error("constraint '" + c->name + "' is defined twice (hint: give each constraint its own name)");
  offsets_.push_back(rows_);
  rows_ += c->rows();
  for (int p : c->points())
    if (std::find(points_.begin(), points_.end(), p) == points_.end()) points_.push_back(p);
  constraints_.push_back(std::move(c));
}

int ConstraintSet::row_owner(int row) const {
  int k = 0;
  while (k + 1 < size() && offsets_[k + 1] <= row) ++k;
  return k;
}

std::string ConstraintSet::row_name(int row) const {
  const int k = row_owner(row);
  const auto& c = constraints_[k];
  return c->rows() == 1 ? c->name : c->name + "[" + std::to_string(row - offsets_[k]) + "]";
}

ConstraintEval::ConstraintEval(const Model& model, const ConstraintSet& set)
    : phi(Eigen::VectorXd::Zero(set.rows())), phid(Eigen::VectorXd::Zero(set.rows())),
      gamma(Eigen::VectorXd::Zero(set.rows())), A(Eigen::MatrixXd::Zero(set.rows(), model.nv)),
      points(model.point_name.size()) {
  int most = 0;
  for (const auto& c : set.constraints()) most = std::max(most, c->scratch_size());
  scratch.assign(static_cast<size_t>(most), 0.0);
  for (auto& p : points) {
    p.C = Eigen::Matrix<double, 3, Eigen::Dynamic>::Zero(3, model.nv);
    p.Jw = Eigen::Matrix<double, 3, Eigen::Dynamic>::Zero(3, model.nv);
  }
}

namespace {
/// Point states from body motions already in data.v, data.a (and data.oMi). `a_offset` is
/// subtracted from every world-frame drift: the base acceleration data.a was propagated with.
void point_states_from_body_motion(const Model& model, const Data& data, const std::vector<int>& pts,
                                   const Vec3& a_offset, std::vector<PointState>& out) {
  for (int k : pts) {
    PointState& P = out[k];
    const int b = model.point_body[k];
    if (b < 0) {
      P.r = model.point_position[k];
      P.v.setZero();
      P.d.setZero();
      P.w.setZero();
      P.wd.setZero();
      P.R.setIdentity();
      P.C.setZero();
      P.Jw.setZero();
      continue;
    }
    const PointDrift pd = kinematics_detail::point_drift_on_body(data, b, model.point_position[k]);
    P.r = data.oMi[b].act_point(model.point_position[k]);
    P.R = data.oMi[b].R;
    P.v = pd.velocity;
    P.d = pd.drift - a_offset;
    P.w = pd.omega;
    P.wd = pd.omega_drift;
    kinematics_detail::point_jacobian_at(model, data, b, P.r, P.C, P.Jw);
  }
}

void compose_world_placements(const Model& model, Data& data) {
  for (int i = 0; i < model.nq; ++i) {
    const int p = model.parent[i];
    data.oMi[i] = p < 0 ? data.liMi[i] : data.oMi[p] * data.liMi[i];
  }
}
}  // namespace

void compute_point_states(const Model& model, Data& data, const std::vector<int>& pts, const Eigen::VectorXd& qd,
                          std::vector<PointState>& out) {
  // Body velocities and drift accelerations (q̈ = 0), body frames.
  for (int i = 0; i < model.nq; ++i) kinematics_detail::propagate_velocity_drift(model, data, i, qd);
  point_states_from_body_motion(model, data, pts, Vec3::Zero(), out);
}

namespace {
void evaluate_rows(const ConstraintSet& set, ConstraintEval& ev, double t, const Eigen::VectorXd& q,
                   const Eigen::VectorXd& qd) {
  const ConstraintInput in{t, q, qd, ev.points, ev.scratch.data()};
  for (int k = 0; k < set.size(); ++k) {
    const auto& c = set.constraints()[k];
    const int r = set.row_offset(k), m = c->rows();
    c->evaluate(in, ev.phi.segment(r, m), ev.phid.segment(r, m), ev.A.middleRows(r, m), ev.gamma.segment(r, m));
  }
}
}  // namespace

void evaluate_constraints(const Model& model, Data& data, const ConstraintSet& set, ConstraintEval& ev, double t,
                          const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  check_data(model, data);
  if (q.size() != model.nq) model.check_q(q);
  if (qd.size() != model.nv) check_vector("qd", qd, model.nv);
  if (ev.phi.size() != set.rows() || ev.A.cols() != model.nv || ev.points.size() != model.point_name.size())
    throw Error("evaluate_constraints: the ConstraintEval was built for another model or constraint set (hint: "
                "ConstraintEval ev(model, set) with the same model and set)");
  unchecked::forward_kinematics(model, data, q);
  compute_point_states(model, data, set.points(), qd, ev.points);
  evaluate_rows(set, ev, t, q, qd);
}

void evaluate_constraints_after_bias_forces(const Model& model, Data& data, const ConstraintSet& set,
                                            ConstraintEval& ev, double t, const Eigen::VectorXd& q,
                                            const Eigen::VectorXd& qd) {
  compose_world_placements(model, data);
  // RNEA with q̈ = 0 left the drift accelerations plus the base acceleration −g, carried into
  // every body as a pure translation: subtract it in the world frame.
  point_states_from_body_motion(model, data, set.points(), -model.gravity, ev.points);
  evaluate_rows(set, ev, t, q, qd);
}

// ---------------- dual-number evaluation ----------------
ConstraintEvalDual::ConstraintEvalDual(const Model& model, const ConstraintSet& set)
    : model_id(model.id), m(set.rows()), n(model.nv), phi(set.rows()), phid(set.rows()), gamma(set.rows()),
      A(static_cast<size_t>(set.rows()) * model.nv), points(model.point_name.size()),
      bodies(multibody::bodies_from_model<JS>(model)), q(model.nv) {
  int most = 0;
  for (const auto& c : set.constraints()) most = std::max(most, c->scratch_size_dual());
  scratch.assign(static_cast<size_t>(most), JS(0.0));
  for (auto& p : points) {
    p.r = p.v = p.d = p.w = p.wd = multibody::zero3<JS>();
    p.R = multibody::identity3<JS>();
    p.C.assign(model.nv, multibody::zero3<JS>());
    p.Jw.assign(model.nv, multibody::zero3<JS>());
  }
  // size the kinematics once (no allocation in the evaluations)
  multibody::forward_poses(bodies, q, poses);
  multibody::forward_motion(bodies, poses, q.data(), static_cast<const JS*>(nullptr), multibody::zero3<JS>(), true,
                            motion);
}

void evaluate_constraints_dual(const Model& model, const ConstraintSet& set, ConstraintEvalDual& ev, const JS& t,
                               const JS* q, const JS* qd) {
  using namespace multibody;
  if (ev.model_id != model.id || ev.m != set.rows() || ev.n != model.nv ||
      ev.points.size() != model.point_name.size())
    throw Error("evaluate_constraints_dual: the ConstraintEvalDual was built for another model or constraint set "
                "(hint: ConstraintEvalDual ev(model, set) with the same model and set)");
  if (!q || !qd) throw Error("evaluate_constraints_dual: expected q and qd (n dual numbers each), got a null pointer");
  const int n = model.nv;
  std::copy(q, q + n, ev.q.begin());
  forward_poses(ev.bodies, ev.q, ev.poses);
  // velocities and drift accelerations (q̈ = 0), base at rest (kinematics, not gravity)
  forward_motion(ev.bodies, ev.poses, qd, static_cast<const JS*>(nullptr), zero3<JS>(), true, ev.motion);
  for (int k : set.points()) {
    PointStateT<JS>& P = ev.points[k];
    const int b = model.point_body[k];
    std::fill(P.C.begin(), P.C.end(), zero3<JS>());
    std::fill(P.Jw.begin(), P.Jw.end(), zero3<JS>());
    if (b < 0) {
      P.r = ev.bodies.points[k].position;
      P.v = P.d = P.w = P.wd = zero3<JS>();
      P.R = identity3<JS>();
      continue;
    }
    const PointKinematics<JS> pk = point_kinematics(ev.bodies.points[k], ev.poses, ev.motion);
    P.r = pk.r;
    P.v = pk.v;
    P.d = pk.a;
    P.R = ev.poses.R[b];
    P.w = mul(P.R, ev.motion.w[b]);
    P.wd = mul(P.R, ev.motion.wd[b]);
    for (int j : model.support[b]) {
      P.C[j] = point_jacobian_column(ev.bodies, ev.poses, j, P.r);
      if (model.joint_type[j] == JointType::Revolute) P.Jw[j] = mul(ev.poses.R[j], ev.bodies.bodies[j].axis);
    }
  }
  std::fill(ev.A.begin(), ev.A.end(), JS(0.0));
  const ConstraintInputDual in{t, n, q, qd, ev.points, ev.scratch.data()};
  for (int k = 0; k < set.size(); ++k) {
    const auto& c = set.constraints()[k];
    const int r = set.row_offset(k);
    c->evaluate_dual(in, ev.phi.data() + r, ev.phid.data() + r, ev.A.data() + static_cast<size_t>(r) * n,
                     ev.gamma.data() + r);
  }
}

}  // namespace refdyn
