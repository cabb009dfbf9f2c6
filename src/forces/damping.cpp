// damping: viscous joint damping, τ = −b q̇_j (law below; apply, apply_dual, ∂Q/∂q̇ and the rate
// −b q̈_j are its instantiations, ForceLaw).
#include "element_support.hpp"

#include <cmath>

namespace refdyn {

namespace {

class JointDamping final : public ForceLaw<JointDamping> {
 public:
  JointDamping(int j, std::string n, Number b) : j_(j), n_(std::move(n)), b_(std::move(b)) {}
  std::string name() const override { return "damping(" + n_ + ")"; }
  template <class S>
  void law(const S&, const S*, const S* qd, const S*, S* Q, S*) const {
    Q[j_] -= param<S>(b_) * qd[j_];
  }
 private:
  int j_;
  std::string n_;
  Number b_;
};

}  // namespace

NewForceElement joint_damping(const Model& model, const std::string& joint, Number b) {
  force_detail::need(std::isfinite(b.value) && b >= 0, "damping coefficient of joint '" + joint + "'",
                     "a finite value >= 0", b);
  return std::make_shared<JointDamping>(model.joint_index(joint), joint, b);
}

}  // namespace refdyn
