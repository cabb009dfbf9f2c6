// joint_coupling: two joints coupled linearly (a gear pair, a URDF <mimic>),
//   Φ = q_j − r q_l − o,  Φ̇ = q̇_j − r q̇_l,  A = e_jᵀ − r e_lᵀ,  γ = 0.
#include "kind_support.hpp"

#include <cmath>

namespace refdyn {

namespace {

class JointCoupling final : public ConstraintLaw<JointCoupling> {
 public:
  JointCoupling(int j, int l, std::string jn, std::string ln, Number ratio, Number offset)
      : j_(j), l_(l), jn_(std::move(jn)), ln_(std::move(ln)), ratio_(std::move(ratio)), offset_(std::move(offset)) {}
  template <class S>
  void law(const LawInput<S>& in, LawRows<S>& out) const {
    out.phi[0] = in.q[j_] - S(param<S>(ratio_)) * in.q[l_] - S(param<S>(offset_));
    out.phid[0] = in.qd[j_] - S(param<S>(ratio_)) * in.qd[l_];
    out.A_zero(0);
    out.A_set(0, j_, S(1.0));
    out.A_set(0, l_, S(-ratio_.value));
    out.gamma[0] = S(0.0);
  }
  int rows() const override { return 1; }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return false; }
  std::string describe() const override {
    return "q(" + jn_ + ") - " + fmt(ratio_) + "*q(" + ln_ + ") - " + fmt(offset_) + " = 0";
  }
 private:
  int j_, l_;
  std::string jn_, ln_;
  Number ratio_, offset_;
};

}  // namespace

NewConstraint joint_coupling(const Model& m, const std::string& joint, const std::string& leader, Number ratio,
                             Number offset, ConstraintOrigin o) {
  if (!std::isfinite(ratio.value) || !std::isfinite(offset.value))
    throw Error(expected_got("joint_coupling ratio and offset", "finite numbers", fmt(ratio) + ", " + fmt(offset)));
  const int j = m.joint_index(joint), l = m.joint_index(leader);
  if (j == l) throw Error("joint_coupling: joint '" + joint + "' cannot be coupled to itself (hint: name another leader)");
  return constraint_detail::named(std::make_shared<JointCoupling>(j, l, joint, leader, ratio, offset),
                                  joint + "_from_" + leader, o);
}

}  // namespace refdyn
