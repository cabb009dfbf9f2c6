// expression: a constraint written as an expression over task quantities (expression.hpp), of
// order position, velocity or acceleration, chained through the point kinematics (law below).
#include "kind_support.hpp"
#include "refdyn/expression/expression.hpp"
#include "refdyn/expression/time_function.hpp"

#include <algorithm>
#include <cctype>

namespace refdyn {

namespace {

enum class VarKind { PointCoord, PointVel, PointAcc, Joint, JointVel, JointAcc, Time };
struct Var {
  VarKind kind;
  int index = 0;  // point or joint
  int axis = 0;
};

bool is_acceleration(VarKind k) { return k == VarKind::PointAcc || k == VarKind::JointAcc; }
bool is_point(VarKind k) { return k == VarKind::PointCoord || k == VarKind::PointVel || k == VarKind::PointAcc; }

/// The variables an expression of this order may use: x(P).. and q(j) always; vx(P).. and
/// qd(j) from order 1; ax(P).. and qdd(j) at order 2.
std::vector<std::string> candidate_names(const Model& m, int order, std::vector<Var>& vars) {
  std::vector<std::string> names;
  const char* ax[] = {"x", "y", "z"};
  for (size_t p = 0; p < m.point_name.size(); ++p)
    for (int a = 0; a < 3; ++a) {
      names.push_back(std::string(ax[a]) + "(" + m.point_name[p] + ")");
      vars.push_back({VarKind::PointCoord, static_cast<int>(p), a});
      if (order >= 1) {
        names.push_back(std::string("v") + ax[a] + "(" + m.point_name[p] + ")");
        vars.push_back({VarKind::PointVel, static_cast<int>(p), a});
      }
      if (order >= 2) {
        names.push_back(std::string("a") + ax[a] + "(" + m.point_name[p] + ")");
        vars.push_back({VarKind::PointAcc, static_cast<int>(p), a});
      }
    }
  for (int j = 0; j < m.nq; ++j) {
    names.push_back("q(" + m.joint_name[j] + ")");
    vars.push_back({VarKind::Joint, j, 0});
    if (order >= 1) {
      names.push_back("qd(" + m.joint_name[j] + ")");
      vars.push_back({VarKind::JointVel, j, 0});
    }
    if (order >= 2) {
      names.push_back("qdd(" + m.joint_name[j] + ")");
      vars.push_back({VarKind::JointAcc, j, 0});
    }
  }
  names.push_back("t");
  vars.push_back({VarKind::Time, 0, 0});
  return names;
}

bool mentions(const std::string& text, std::initializer_list<const char*> calls) {
  for (const char* c : calls)
    for (size_t pos = text.find(c); pos != std::string::npos; pos = text.find(c, pos + 1)) {
      // a call name must not continue an identifier (vx( inside "avx(" is not vx()
      if (pos > 0 && (std::isalnum(static_cast<unsigned char>(text[pos - 1])) || text[pos - 1] == '_')) continue;
      return true;
    }
  return false;
}

class ExpressionConstraint final : public ConstraintLaw<ExpressionConstraint> {
 public:
  static constexpr bool kOwnSymbolicForm = true;  // its law is the compiled tape, its text the scenario's
  ExpressionConstraint(const Model& m, const std::string& name, const std::string& text, int order,
                       const std::map<std::string, double>& params)
      : order_(order), text_(text), params_(params) {
    std::vector<Var> all;
    const std::vector<std::string> names = candidate_names(m, order, all);
    std::unique_ptr<Expression> probe;
    try {
      probe = std::make_unique<Expression>(text, names, params, 0);
    } catch (const Error& e) {
      std::string hint;
      if (order < 2 && mentions(text, {"ax(", "ay(", "az(", "qdd("}))
        hint = " (hint: accelerations ax(P), ay(P), az(P), qdd(j) are allowed only in acceleration constraints, "
               "order: acceleration)";
      else if (order < 1 && mentions(text, {"vx(", "vy(", "vz(", "qd("}))
        hint = " (hint: velocities vx(P), vy(P), vz(P), qd(j) are allowed only in first-order constraints)";
      else if (mentions(text, {"jx(", "jy(", "jz(", "qddd("}))
        hint = " (hint: jerks jx(P), jy(P), jz(P), qddd(j) are allowed only in jerk constraints, order: jerk)";
      throw Error("constraint '" + name + "': " + e.what() + hint);
    }
    // State dependence from the variables left after the parameters are substituted; the
    // expression itself is rebuilt over every variable written in the text (a parameter may
    // cancel one, as in k*q(j2) with k = 0, and a rebuild without it would not know the name).
    bool depends_on_state = false, depends_on_acceleration = false;
    for (int k : probe->used_variables()) {
      depends_on_state = depends_on_state || all[k].kind != VarKind::Time;
      depends_on_acceleration = depends_on_acceleration || is_acceleration(all[k].kind);
      if (all[k].kind == VarKind::Time) rheonomic_ = true;
    }
    if (!depends_on_state)
      throw Error("constraint '" + name + "': the expression does not depend on the state (after substituting the "
                  "parameters it is " + probe->text() + "); a constraint must involve q, qd or a point");
    if (order == 2 && !depends_on_acceleration)
      throw Error("constraint '" + name + "': order: acceleration, but the expression (after substituting the "
                  "parameters: " + probe->text() + ") involves no acceleration ax(P), ay(P), az(P) or qdd(j) "
                  "(hint: write it as a position or velocity constraint, or differentiate it)");
    std::vector<std::string> used_names;
    for (int k : probe->referenced_variables()) {
      used_names.push_back(names[k]);
      vars_.push_back(all[k]);
      if (is_point(all[k].kind))
        if (std::find(points_.begin(), points_.end(), all[k].index) == points_.end()) points_.push_back(all[k].index);
    }
    expr_ = std::make_unique<Expression>(text, used_names, params, order == 1 ? 1 : 2);
    if (order == 2) {
      // The paper's form B q̈ + s = 0: linear in the accelerations, i.e. every second derivative
      // between two acceleration variables vanishes identically (symbolically).
      for (size_t i = 0; i < vars_.size(); ++i)
        for (size_t j = i; j < vars_.size(); ++j)
          if (is_acceleration(vars_[i].kind) && is_acceleration(vars_[j].kind) &&
              expr_->second_derivative_text(static_cast<int>(i), static_cast<int>(j)) != "0")
            throw Error("constraint '" + name + "': order: acceleration expects an expression linear in the "
                        "accelerations (B(t, q, qd) qdd + s = 0), but d2f/d" + used_names[i] + "d" + used_names[j] +
                        " = " + expr_->second_derivative_text(static_cast<int>(i), static_cast<int>(j)) +
                        " is not zero");
    }
  }
  int scratch_size() const override {
    const int n = static_cast<int>(vars_.size());
    return 3 * n + n * n;  // w, ẇ, gradient, Hessian
  }
  int scratch_size_dual() const override {
    const int n = static_cast<int>(vars_.size());
    return 3 * n + n * n + expr_->register_count();  // w, ẇ, gradient, Hessian, tape registers
  }
  int rows() const override { return 1; }
  bool first_order() const override { return order_ == 1; }
  int order() const override { return order_; }
  bool rheonomic() const override { return rheonomic_; }
  std::vector<int> points() const override { return points_; }
  std::string describe() const override { return text_ + " = 0"; }
  std::optional<SymbolicForm> symbolic(const Model&) const override { return symbolic_rows({text_}, params_); }

  /// Φ (or c) = f(w) of the variables w (point coordinates, velocities, accelerations, joint
  /// values and rates, t), chained through the point kinematics:
  ///   order 0:  A = Σ f_k ∂w_k/∂q,  Φ̇ = Σ f_k ẇ_k,  γ = Σ f_k (drift of w_k) + ẇᵀ f_ww ẇ
  ///   order 1:  A = Σ f_k ∂w_k/∂q̇,  γ = Σ f_k ẇ_k|_{q̈=0}
  ///   order 2:  B q̈ + s = 0 with f linear in the accelerations: s = f(w) at q̈ = 0 (point
  ///             accelerations = their drifts d, qdd(j) = 0), A = B = Σ_acc f_k ∂w_k/∂q̈; Φ = Φ̇ = 0.
  ///             Exact: f(w(q̈)) = s + B q̈ because f_k of an acceleration variable does not
  ///             depend on the accelerations.
  /// The expression's value, gradient and Hessian come from its tape over S (the dual tape
  /// differentiates their dependence on q, q̇ through w).
  template <class S>
  void law(const LawInput<S>& in, LawRows<S>& out) const {
    using law_ops::skippable;
    const size_t n = vars_.size();
    if (!in.scratch)
      throw Error("constraint '" + name + "': the input's scratch is null (hint: evaluate with a ConstraintEval or "
                  "ConstraintEvalDual, which own scratch_size() doubles and scratch_size_dual() dual numbers)");
    S* w = in.scratch;
    S* wd = w + n;
    S* grad = wd + n;
    S* hess = grad + n;
    S* regs = hess + n * n;  // the dual tape's registers (scratch_size_dual); unused by the double tape
    for (size_t k = 0; k < n; ++k) {
      const Var& v = vars_[k];
      wd[k] = S(0.0);
      switch (v.kind) {
        case VarKind::PointCoord:
          w[k] = in.points[v.index].r[v.axis];
          wd[k] = in.points[v.index].v[v.axis];
          break;
        case VarKind::PointVel: w[k] = in.points[v.index].v[v.axis]; break;
        case VarKind::PointAcc: w[k] = order_ == 2 ? in.points[v.index].d[v.axis] : S(0.0); break;
        case VarKind::Joint:
          w[k] = in.q[v.index];
          wd[k] = in.qd[v.index];
          break;
        case VarKind::JointVel: w[k] = in.qd[v.index]; break;
        case VarKind::JointAcc: w[k] = S(0.0); break;
        case VarKind::Time:
          w[k] = in.t;  // a seeded t differentiates f's explicit time dependence
          wd[k] = S(1.0);
          break;
      }
    }
    out.A_zero(0);
    S f = S(0.0);
    if (order_ == 2) {
      evaluate_tape(w, f, grad, nullptr, regs);
      for (size_t k = 0; k < n; ++k) {
        const Var& v = vars_[k];
        if (skippable(grad[k])) continue;
        if (v.kind == VarKind::PointAcc) out.A_add_axis(0, grad[k], in.points[v.index].C, v.axis);
        else if (v.kind == VarKind::JointAcc) out.A_add(0, v.index, grad[k]);
      }
      out.gamma[0] = f;
      out.phi[0] = S(0.0);
      out.phid[0] = S(0.0);
      return;
    }
    const bool first = order_ == 1;
    evaluate_tape(w, f, grad, first ? nullptr : hess, regs);
    out.phi[0] = f;
    S g = S(0.0);
    for (size_t k = 0; k < n; ++k) {
      const Var& v = vars_[k];
      const S& fk = grad[k];
      if (skippable(fk)) continue;
      const auto* P = is_point(v.kind) ? &in.points[v.index] : nullptr;
      if (!first) {
        if (v.kind == VarKind::PointCoord) {
          out.A_add_axis(0, fk, P->C, v.axis);
          g += fk * P->d[v.axis];
        } else if (v.kind == VarKind::Joint) {
          out.A_add(0, v.index, fk);
        }
      } else {
        switch (v.kind) {
          case VarKind::PointVel:
            out.A_add_axis(0, fk, P->C, v.axis);
            g += fk * P->d[v.axis];
            break;
          case VarKind::JointVel: out.A_add(0, v.index, fk); break;
          case VarKind::PointCoord: g += fk * P->v[v.axis]; break;
          case VarKind::Joint: g += fk * in.qd[v.index]; break;
          case VarKind::Time: g += fk; break;
          case VarKind::PointAcc:
          case VarKind::JointAcc: break;
        }
      }
    }
    if (first) {
      out.phid[0] = f;
    } else {
      S fd = S(0.0), quad = S(0.0);
      for (size_t k = 0; k < n; ++k) {
        fd += grad[k] * wd[k];
        if (skippable(wd[k])) continue;
        for (size_t l = 0; l < n; ++l) quad += wd[k] * hess[k * n + l] * wd[l];
      }
      out.phid[0] = fd;
      g += quad;
    }
    out.gamma[0] = g;
  }

 private:
  void evaluate_tape(const double* w, double& f, double* grad, double* hess, double*) const {
    expr_->evaluate(w, f, grad, hess);
  }
  void evaluate_tape(const JacobianScalar* w, JacobianScalar& f, JacobianScalar* grad, JacobianScalar* hess,
                     JacobianScalar* regs) const {
    expr_->evaluate(w, f, grad, hess, regs);
  }

  int order_;
  bool rheonomic_ = false;
  std::string text_;
  std::map<std::string, double> params_;
  std::vector<Var> vars_;
  std::vector<int> points_;
  std::unique_ptr<Expression> expr_;
};

}  // namespace

NewConstraint expression_constraint(const Model& model, const std::string& name, const std::string& text,
                                    ConstraintOrder order, const std::map<std::string, double>& parameters,
                                    ConstraintOrigin origin) {
  if (name.empty()) throw Error("expression_constraint: expected a name, got an empty one");
  auto c = std::make_shared<ExpressionConstraint>(model, name, text, static_cast<int>(order), parameters);
  c->name = name;
  c->origin = origin;
  return c;
}

NewConstraint expression_constraint(const Model& model, const std::string& name, const std::string& text,
                                    bool first_order, const std::map<std::string, double>& parameters,
                                    ConstraintOrigin origin) {
  return expression_constraint(model, name, text, first_order ? ConstraintOrder::Velocity : ConstraintOrder::Position,
                               parameters, origin);
}

}  // namespace refdyn
