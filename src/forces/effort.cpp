// effort: a prescribed joint torque or force, τ = f(t) (law below; its rate is f'(t) through the
// seeded time of ForceLaw's rate sweep).
#include "element_support.hpp"

namespace refdyn {

namespace {

class JointEffort final : public ForceLaw<JointEffort> {
 public:
  JointEffort(int j, std::string n, TimeFunctionPtr f) : j_(j), n_(std::move(n)), f_(std::move(f)) {}
  std::string name() const override { return "effort(" + n_ + ")"; }
  bool actuator() const override { return true; }
  template <class S>
  void law(const S& t, const S*, const S*, const S*, S* Q, S*) const {
    Q[j_] += time_value(*f_, t).f;
  }
 private:
  int j_;
  std::string n_;
  TimeFunctionPtr f_;
};

}  // namespace

NewForceElement joint_effort(const Model& model, const std::string& joint, TimeFunctionPtr f) {
  if (!f) throw Error("joint_effort: expected a time function, got none");
  return std::make_shared<JointEffort>(model.joint_index(joint), joint, std::move(f));
}

}  // namespace refdyn
