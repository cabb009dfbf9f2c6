// Constraints and time functions written as symbolic expressions (expression.hpp).
#include "refdyn/constraints.hpp"
#include "refdyn/error.hpp"
#include "refdyn/expression.hpp"
#include "refdyn/time_function.hpp"

#include <algorithm>

namespace refdyn {

namespace {

enum class VarKind { PointCoord, PointVel, Joint, JointVel, Time };
struct Var {
  VarKind kind;
  int index = 0;  // point or joint
  int axis = 0;
};

std::vector<std::string> candidate_names(const Model& m, bool first_order, std::vector<Var>& vars) {
  std::vector<std::string> names;
  const char* ax[] = {"x", "y", "z"};
  for (size_t p = 0; p < m.point_name.size(); ++p)
    for (int a = 0; a < 3; ++a) {
      names.push_back(std::string(ax[a]) + "(" + m.point_name[p] + ")");
      vars.push_back({VarKind::PointCoord, static_cast<int>(p), a});
      if (first_order) {
        names.push_back(std::string("v") + ax[a] + "(" + m.point_name[p] + ")");
        vars.push_back({VarKind::PointVel, static_cast<int>(p), a});
      }
    }
  for (int j = 0; j < m.nq; ++j) {
    names.push_back("q(" + m.joint_name[j] + ")");
    vars.push_back({VarKind::Joint, j, 0});
    if (first_order) {
      names.push_back("qd(" + m.joint_name[j] + ")");
      vars.push_back({VarKind::JointVel, j, 0});
    }
  }
  names.push_back("t");
  vars.push_back({VarKind::Time, 0, 0});
  return names;
}

class ExpressionConstraint final : public Constraint {
 public:
  ExpressionConstraint(const Model& m, const std::string& name, const std::string& text, bool first_order,
                       const std::map<std::string, double>& params)
      : first_order_(first_order), text_(text), params_(params) {
    std::vector<Var> all;
    const std::vector<std::string> names = candidate_names(m, first_order, all);
    std::unique_ptr<Expression> probe;
    try {
      probe = std::make_unique<Expression>(text, names, params, 0);
    } catch (const Error& e) {
      std::string hint;
      if (!first_order && (text.find("vx(") != std::string::npos || text.find("vy(") != std::string::npos ||
                           text.find("vz(") != std::string::npos || text.find("qd(") != std::string::npos))
        hint = " (hint: velocities vx(P), vy(P), vz(P), qd(j) are allowed only in first-order constraints)";
      throw Error("constraint '" + name + "': " + e.what() + hint);
    }
    // State dependence from the variables left after the parameters are substituted; the
    // expression itself is rebuilt over every variable written in the text (a parameter may
    // cancel one, as in k*q(j2) with k = 0, and a rebuild without it would not know the name).
    bool depends_on_state = false;
    for (int k : probe->used_variables()) {
      depends_on_state = depends_on_state || all[k].kind != VarKind::Time;
      if (all[k].kind == VarKind::Time) rheonomic_ = true;
    }
    if (!depends_on_state)
      throw Error("constraint '" + name + "': the expression does not depend on the state (after substituting the "
                  "parameters it is " + probe->text() + "); a constraint must involve q, qd or a point");
    std::vector<std::string> used_names;
    for (int k : probe->referenced_variables()) {
      used_names.push_back(names[k]);
      vars_.push_back(all[k]);
      if (all[k].kind == VarKind::PointCoord || all[k].kind == VarKind::PointVel)
        if (std::find(points_.begin(), points_.end(), all[k].index) == points_.end()) points_.push_back(all[k].index);
    }
    expr_ = std::make_unique<Expression>(text, used_names, params, first_order ? 1 : 2);
  }
  int scratch_size() const override {
    const int n = static_cast<int>(vars_.size());
    return 3 * n + n * n;  // w, ẇ, gradient, Hessian
  }
  int rows() const override { return 1; }
  bool first_order() const override { return first_order_; }
  bool rheonomic() const override { return rheonomic_; }
  std::vector<int> points() const override { return points_; }
  std::string describe() const override { return text_ + " = 0"; }
  std::optional<SymbolicForm> symbolic() const override { return symbolic_rows({text_}, params_); }

  void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi, Eigen::Ref<Eigen::VectorXd> phid,
                Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    const size_t n = vars_.size();
    if (!in.scratch)
      throw Error("constraint '" + name + "': ConstraintInput::scratch is null (hint: evaluate with a ConstraintEval, "
                  "which owns scratch_size() doubles)");
    double* w = in.scratch;
    double* wd = w + n;
    double* grad = wd + n;
    double* hess = grad + n;
    // Values w and, for holonomic constraints, their rates ẇ.
    for (size_t k = 0; k < n; ++k) {
      const Var& v = vars_[k];
      switch (v.kind) {
        case VarKind::PointCoord:
          w[k] = in.points[v.index].r[v.axis];
          wd[k] = in.points[v.index].v[v.axis];
          break;
        case VarKind::PointVel:
          w[k] = in.points[v.index].v[v.axis];
          wd[k] = 0;
          break;
        case VarKind::Joint:
          w[k] = in.q[v.index];
          wd[k] = in.qd[v.index];
          break;
        case VarKind::JointVel:
          w[k] = in.qd[v.index];
          wd[k] = 0;
          break;
        case VarKind::Time:
          w[k] = in.t;
          wd[k] = 1.0;
          break;
      }
    }
    double f = 0;
    expr_->evaluate(w, f, grad, first_order_ ? nullptr : hess);
    phi[0] = f;
    A.row(0).setZero();
    double g = 0;
    for (size_t k = 0; k < n; ++k) {
      const Var& v = vars_[k];
      const double fk = grad[k];
      if (fk == 0) continue;
      const PointState* P = (v.kind == VarKind::PointCoord || v.kind == VarKind::PointVel) ? &in.points[v.index] : nullptr;
      if (!first_order_) {
        // A = Σ f_k ∂w_k/∂q, γ gets f_k · (drift of w_k)
        if (v.kind == VarKind::PointCoord) {
          A.row(0) += fk * P->C.row(v.axis);
          g += fk * P->d[v.axis];
        } else if (v.kind == VarKind::Joint) {
          A(0, v.index) += fk;
        }
      } else {
        // A = Σ f_k ∂w_k/∂q̇, γ = Σ f_k ẇ_k|_{q̈=0}
        switch (v.kind) {
          case VarKind::PointVel:
            A.row(0) += fk * P->C.row(v.axis);
            g += fk * P->d[v.axis];
            break;
          case VarKind::JointVel: A(0, v.index) += fk; break;
          case VarKind::PointCoord: g += fk * P->v[v.axis]; break;
          case VarKind::Joint: g += fk * in.qd[v.index]; break;
          case VarKind::Time: g += fk; break;
        }
      }
    }
    if (first_order_) {
      phid[0] = f;
    } else {
      double fd = 0, quad = 0;
      for (size_t k = 0; k < n; ++k) {
        fd += grad[k] * wd[k];
        if (wd[k] == 0) continue;
        for (size_t l = 0; l < n; ++l) quad += wd[k] * hess[k * n + l] * wd[l];
      }
      phid[0] = fd;
      g += quad;
    }
    gamma[0] = g;
  }

 private:
  bool first_order_;
  bool rheonomic_ = false;
  std::string text_;
  std::map<std::string, double> params_;
  std::vector<Var> vars_;
  std::vector<int> points_;
  std::unique_ptr<Expression> expr_;
};

class ExpressionTimeFunction final : public TimeFunction {
 public:
  ExpressionTimeFunction(const std::string& text, const std::map<std::string, double>& params)
      : text_(text), params_(params), expr_(text, {"t"}, params, 2) {}
  std::optional<SymbolicForm> symbolic() const override { return symbolic_rows({text_}, params_); }
  TimeValue eval(double t) const override {
    TimeValue v;
    expr_.evaluate(&t, v.f, &v.df, &v.ddf);
    return v;
  }
  std::string describe() const override { return text_; }
 private:
  std::string text_;
  std::map<std::string, double> params_;
  Expression expr_;
};

}  // namespace

ConstraintPtr expression_constraint(const Model& model, const std::string& name, const std::string& text,
                                    bool first_order, const std::map<std::string, double>& parameters,
                                    ConstraintOrigin origin) {
  if (name.empty()) throw Error("expression_constraint: expected a name, got an empty one");
  auto c = std::make_shared<ExpressionConstraint>(model, name, text, first_order, parameters);
  c->name = name;
  c->origin = origin;
  return c;
}

TimeFunctionPtr expression_time_function(const std::string& text, const std::map<std::string, double>& parameters) {
  try {
    return std::make_shared<ExpressionTimeFunction>(text, parameters);
  } catch (const Error& e) {
    throw Error(std::string("time function: ") + e.what());
  }
}

}  // namespace refdyn
