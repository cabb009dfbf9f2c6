// joint_trajectory: prescribed joint motion, Φ = q_j − f(t),  Φ̇ = q̇_j − f',  A = e_jᵀ,  γ = −f''.
#include "kind_support.hpp"

namespace refdyn {

namespace {

class JointTrajectory final : public ConstraintLaw<JointTrajectory> {
 public:
  JointTrajectory(int j, std::string jn, TimeFunctionPtr f) : j_(j), jn_(std::move(jn)), f_(std::move(f)) {}
  template <class S>
  void law(const LawInput<S>& in, LawRows<S>& out) const {
    const auto f = time_value(*f_, in.t);
    out.phi[0] = in.q[j_] - f.f;
    out.phid[0] = in.qd[j_] - f.df;
    out.A_zero(0);
    out.A_set(0, j_, S(1.0));
    out.gamma[0] = law_ops::neg(f.ddf);
  }
  int rows() const override { return 1; }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return true; }
  std::string describe() const override { return "q(" + jn_ + ") - (" + f_->describe() + ") = 0"; }
  const TimeFunction* target() const override { return f_.get(); }
 private:
  int j_;
  std::string jn_;
  TimeFunctionPtr f_;
};

}  // namespace

NewConstraint joint_trajectory(const Model& m, const std::string& joint, TimeFunctionPtr f, ConstraintOrigin o) {
  if (!f) throw Error("joint_trajectory: expected a time function, got none");
  return constraint_detail::named(std::make_shared<JointTrajectory>(m.joint_index(joint), joint, std::move(f)),
                                  "q_" + joint, o);
}

}  // namespace refdyn
