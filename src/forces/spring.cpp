// spring: a linear joint spring, τ = −k (q_j − q_rest) (law below; ForceLaw derives the rest).
#include "element_support.hpp"

#include <cmath>

namespace refdyn {

namespace {

class JointSpring final : public ForceLaw<JointSpring> {
 public:
  JointSpring(int j, std::string n, Number k, Number r) : j_(j), n_(std::move(n)), k_(std::move(k)), r_(std::move(r)) {}
  std::string name() const override { return "spring(" + n_ + ")"; }
  template <class S>
  void law(const S&, const S* q, const S*, const S*, S* Q, S*) const {
    Q[j_] -= param<S>(k_) * (q[j_] - param<S>(r_));
  }
 private:
  int j_;
  std::string n_;
  Number k_, r_;
};

}  // namespace

NewForceElement joint_spring(const Model& model, const std::string& joint, Number k, Number q_rest) {
  force_detail::need(std::isfinite(k.value) && k >= 0, "spring stiffness of joint '" + joint + "'",
                     "a finite value >= 0", k);
  force_detail::need(std::isfinite(q_rest.value), "spring rest position of joint '" + joint + "'", "a finite value",
                     q_rest);
  return std::make_shared<JointSpring>(model.joint_index(joint), joint, k, q_rest);
}

}  // namespace refdyn
