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
    Q[j_] -= k_.value * (q[j_] - r_.value);
  }
  std::optional<SymbolicForm> symbolic() const override {
    SymbolicForm f;
    f.rows = {"-" + symbolic_number(k_) + "*(q(" + n_ + ") - " + symbolic_number(r_) + ")"};
    f.scenario_texts = any_text(k_, r_);
    f.joints = {j_};
    return f;
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
