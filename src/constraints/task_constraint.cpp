// Constraints and time functions written as symbolic expressions (expression.hpp).
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/common/error.hpp"
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

class ExpressionConstraint final : public Constraint {
 public:
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
  std::optional<SymbolicForm> symbolic() const override { return symbolic_rows({text_}, params_); }

  void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi, Eigen::Ref<Eigen::VectorXd> phid,
                Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    const size_t n = vars_.size();
    if (!in.scratch)
      throw Error("constraint '" + name + "': ConstraintInput::scratch is null (hint: evaluate with a ConstraintEval, "
                  "which owns scratch_size() doubles)");
    if (order_ == 2) return evaluate_acceleration(in, phi, phid, A, gamma);
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
        case VarKind::PointAcc:
        case VarKind::JointAcc:  // not among the variables below order 2
          w[k] = wd[k] = 0;
          break;
      }
    }
    const bool first_order_ = order_ == 1;
    double f = 0;
    expr_->evaluate(w, f, grad, first_order_ ? nullptr : hess);
    phi[0] = f;
    A.row(0).setZero();
    double g = 0;
    for (size_t k = 0; k < n; ++k) {
      const Var& v = vars_[k];
      const double fk = grad[k];
      if (fk == 0) continue;
      const PointState* P = is_point(v.kind) ? &in.points[v.index] : nullptr;
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
          case VarKind::PointAcc:
          case VarKind::JointAcc: break;
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

  /// evaluate() over dual numbers: the same formulas, with the expression's value, gradient and
  /// Hessian from the dual tape (Expression::evaluate over JacobianScalar), so their
  /// dependence on q, q̇ (through w) is differentiated exactly. No term is skipped on a zero
  /// value (a zero f_k may have non-zero derivatives).
  void evaluate_dual(const ConstraintInputDual& in, JacobianScalar* phi, JacobianScalar* phid, JacobianScalar* A,
                     JacobianScalar* gamma) const override {
    using JS = JacobianScalar;
    const size_t n = vars_.size();
    const int nq = in.n;
    if (!in.scratch)
      throw Error("constraint '" + name + "': ConstraintInputDual::scratch is null (hint: evaluate with a "
                  "ConstraintEvalDual, which owns scratch_size_dual() dual numbers)");
    JS* w = in.scratch;
    JS* wd = w + n;
    JS* grad = wd + n;
    JS* hess = grad + n;
    JS* regs = hess + n * n;
    const JS zero(0.0);
    for (size_t k = 0; k < n; ++k) {
      const Var& v = vars_[k];
      wd[k] = zero;
      switch (v.kind) {
        case VarKind::PointCoord:
          w[k] = in.points[v.index].r[v.axis];
          wd[k] = in.points[v.index].v[v.axis];
          break;
        case VarKind::PointVel: w[k] = in.points[v.index].v[v.axis]; break;
        case VarKind::PointAcc: w[k] = order_ == 2 ? in.points[v.index].d[v.axis] : zero; break;
        case VarKind::Joint:
          w[k] = in.q[v.index];
          wd[k] = in.qd[v.index];
          break;
        case VarKind::JointVel: w[k] = in.qd[v.index]; break;
        case VarKind::JointAcc: w[k] = zero; break;
        case VarKind::Time:
          w[k] = in.t;  // a seeded t differentiates f's explicit time dependence
          wd[k] = JS(1.0);
          break;
      }
    }
    std::fill_n(A, nq, zero);
    JS f = zero;
    if (order_ == 2) {
      // B q̈ + s = 0: s = f at q̈ = 0, B = Σ_acc f_w ∂w/∂q̈
      expr_->evaluate(w, f, grad, nullptr, regs);
      for (size_t k = 0; k < n; ++k) {
        const Var& v = vars_[k];
        if (v.kind == VarKind::PointAcc) {
          const auto& C = in.points[v.index].C;
          for (int j = 0; j < nq; ++j) A[j] += grad[k] * C[j][v.axis];
        } else if (v.kind == VarKind::JointAcc) {
          A[v.index] += grad[k];
        }
      }
      gamma[0] = f;
      phi[0] = zero;
      phid[0] = zero;
      return;
    }
    const bool first = order_ == 1;
    expr_->evaluate(w, f, grad, first ? nullptr : hess, regs);
    phi[0] = f;
    JS g = zero;
    for (size_t k = 0; k < n; ++k) {
      const Var& v = vars_[k];
      const JS& fk = grad[k];
      const PointStateT<JS>* P = is_point(v.kind) ? &in.points[v.index] : nullptr;
      if (!first) {
        if (v.kind == VarKind::PointCoord) {
          for (int j = 0; j < nq; ++j) A[j] += fk * P->C[j][v.axis];
          g += fk * P->d[v.axis];
        } else if (v.kind == VarKind::Joint) {
          A[v.index] += fk;
        }
      } else {
        switch (v.kind) {
          case VarKind::PointVel:
            for (int j = 0; j < nq; ++j) A[j] += fk * P->C[j][v.axis];
            g += fk * P->d[v.axis];
            break;
          case VarKind::JointVel: A[v.index] += fk; break;
          case VarKind::PointCoord: g += fk * P->v[v.axis]; break;
          case VarKind::Joint: g += fk * in.qd[v.index]; break;
          case VarKind::Time: g += fk; break;
          case VarKind::PointAcc:
          case VarKind::JointAcc: break;
        }
      }
    }
    if (first) {
      phid[0] = f;
    } else {
      JS fd = zero, quad = zero;
      for (size_t k = 0; k < n; ++k) {
        fd += grad[k] * wd[k];
        for (size_t l = 0; l < n; ++l) quad += wd[k] * hess[k * n + l] * wd[l];
      }
      phid[0] = fd;
      g += quad;
    }
    gamma[0] = g;
  }

 private:
  /// B q̈ + s = 0 with f linear in the accelerations: s = f(w) at q̈ = 0 (point accelerations
  /// replaced by their drifts d, qdd(j) by 0), B = Σ_acc f_w ∂w/∂q̈. Exact: f(w(q̈)) = s + B q̈
  /// because f_w of an acceleration variable does not depend on the accelerations.
  void evaluate_acceleration(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi,
                             Eigen::Ref<Eigen::VectorXd> phid, Eigen::Ref<Eigen::MatrixXd> A,
                             Eigen::Ref<Eigen::VectorXd> gamma) const {
    const size_t n = vars_.size();
    double* w = in.scratch;
    double* grad = w + 2 * n;
    for (size_t k = 0; k < n; ++k) {
      const Var& v = vars_[k];
      switch (v.kind) {
        case VarKind::PointCoord: w[k] = in.points[v.index].r[v.axis]; break;
        case VarKind::PointVel: w[k] = in.points[v.index].v[v.axis]; break;
        case VarKind::PointAcc: w[k] = in.points[v.index].d[v.axis]; break;
        case VarKind::Joint: w[k] = in.q[v.index]; break;
        case VarKind::JointVel: w[k] = in.qd[v.index]; break;
        case VarKind::JointAcc: w[k] = 0; break;
        case VarKind::Time: w[k] = in.t; break;
      }
    }
    double s = 0;
    expr_->evaluate(w, s, grad, nullptr);
    A.row(0).setZero();
    for (size_t k = 0; k < n; ++k) {
      const Var& v = vars_[k];
      const double fk = grad[k];
      if (fk == 0) continue;
      if (v.kind == VarKind::PointAcc) A.row(0) += fk * in.points[v.index].C.row(v.axis);
      else if (v.kind == VarKind::JointAcc) A(0, v.index) += fk;
    }
    gamma[0] = s;
    phi[0] = 0;
    phid[0] = 0;
  }

  int order_;
  bool rheonomic_ = false;
  std::string text_;
  std::map<std::string, double> params_;
  std::vector<Var> vars_;
  std::vector<int> points_;
  std::unique_ptr<Expression> expr_;
};

ExpressionOptions with_third_derivative() {
  ExpressionOptions o;
  o.derivative_order = 2;
  o.extra_derivative_order = 3;
  o.extra_derivative_variable = 0;
  return o;
}

/// f, f', f'' from one tape (value, gradient, Hessian in t); f''' from the expression's second,
/// value-only tape of d³f/dt³, differentiated by GiNaC (ExpressionOptions::extra_derivative_order).
class ExpressionTimeFunction final : public TimeFunction {
 public:
  ExpressionTimeFunction(const std::string& text, const std::map<std::string, double>& params)
      : text_(text), params_(params), expr_(text, {"t"}, params, with_third_derivative()) {}
  std::optional<SymbolicForm> symbolic() const override { return symbolic_rows({text_}, params_); }
  TimeValue eval(double t) const override {
    TimeValue v;
    expr_.evaluate(&t, v.f, &v.df, &v.ddf);
    v.dddf = expr_.extra_derivative(&t);
    return v;
  }
  std::string describe() const override { return text_; }
 private:
  std::string text_;
  std::map<std::string, double> params_;
  Expression expr_;
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

std::string differentiate_expression_text(const Model& model, const std::string& name, const std::string& text,
                                          const std::map<std::string, double>& parameters) {
  // Every variable of every order, with the name of its rate ("" for the jerks: order 4).
  std::vector<std::string> names, rates;
  const char* axes[] = {"x", "y", "z"};
  const char* level[] = {"", "v", "a", "j"};
  for (const std::string& p : model.point_name)
    for (int l = 0; l < 4; ++l)
      for (const char* a : axes) {
        names.push_back(std::string(level[l]) + a + "(" + p + ")");
        rates.push_back(l < 3 ? std::string(level[l + 1]) + a + "(" + p + ")" : std::string());
      }
  const char* joint_level[] = {"q", "qd", "qdd", "qddd"};
  for (const std::string& j : model.joint_name)
    for (int l = 0; l < 4; ++l) {
      names.push_back(std::string(joint_level[l]) + "(" + j + ")");
      rates.push_back(l < 3 ? std::string(joint_level[l + 1]) + "(" + j + ")" : std::string());
    }
  names.push_back("t");
  rates.push_back("1");
  std::unique_ptr<Expression> f;
  try {
    f = std::make_unique<Expression>(text, names, parameters, 1);
  } catch (const Error& e) {
    throw Error("constraint '" + name + "': " + e.what());
  }
  std::string out;
  for (int k : f->used_variables()) {
    const std::string d = f->derivative_text(k);
    if (d == "0") continue;
    if (rates[k].empty())
      throw Error("constraint '" + name + "': differentiate: the expression involves the jerk " + names[k] +
                  ", whose time derivative (order 4) refdyn does not take (hint: differentiate a row of order "
                  "position, velocity or acceleration)");
    if (!out.empty()) out += " + ";
    out += rates[k] == "1" ? "(" + d + ")" : "(" + d + ")*" + rates[k];
  }
  return out.empty() ? "0" : out;
}

TimeFunctionPtr expression_time_function(const std::string& text, const std::map<std::string, double>& parameters) {
  try {
    return std::make_shared<ExpressionTimeFunction>(text, parameters);
  } catch (const Error& e) {
    throw Error(std::string("time function: ") + e.what());
  }
}

}  // namespace refdyn
