// lugre: LuGre friction (paper (4.7)–(4.8)) with the bristle deflection z as state,
//   ż = q̇ − σ0 |q̇| z / g(q̇),  g(q̇) = μk + (μs − μk) exp(−(q̇/q̇_S)²),  τ = −(σ0 z + σ1 ż + σ2 q̇),
// written once (law below): apply (the paper study's arithmetic), apply_dual, ∂Q/∂q̇ and the jerk
// level's rate (with ż) are its instantiations (ForceLaw). |q̇| is differentiated with the
// one-sided derivative +1 at q̇ = 0 (ad::abs).
#include "element_support.hpp"

#include <cmath>

namespace refdyn {

LuGreFriction::LuGreFriction(const Model& model, const std::string& joint, LuGreParams p)
    : j_(model.joint_index(joint)), joint_name_(joint), p_(p) {
  using force_detail::need;
  const std::string w = "LuGre friction of joint '" + joint + "': ";
  need(std::isfinite(p.mu_s.value) && p.mu_s > 0, w + "mu_s", "a finite value > 0", p.mu_s);
  need(std::isfinite(p.mu_k.value) && p.mu_k > 0, w + "mu_k", "a finite value > 0", p.mu_k);
  need(std::isfinite(p.sigma0.value) && p.sigma0 >= 0, w + "sigma0", "a finite value >= 0", p.sigma0);
  need(std::isfinite(p.sigma1.value) && p.sigma1 >= 0, w + "sigma1", "a finite value >= 0", p.sigma1);
  need(std::isfinite(p.sigma2.value) && p.sigma2 >= 0, w + "sigma2", "a finite value >= 0", p.sigma2);
  need(std::isfinite(p.v_stribeck.value) && p.v_stribeck > 0, w + "Stribeck velocity", "a finite value > 0", p.v_stribeck);
}

std::string LuGreFriction::name() const { return "lugre(" + joint_name_ + ")"; }

template <class S>
void LuGreFriction::law(const S&, const S*, const S* qd, const S* z, S* Q, S* zdot) const {
  using std::abs;
  using std::exp;
  const S& v = qd[j_];
  const S r = v / param<S>(p_.v_stribeck);
  const S e = exp(-r * r);
  const S g = param<S>(p_.mu_k) + (param<S>(p_.mu_s) - param<S>(p_.mu_k)) * e;
  const S av = abs(v);
  const S zd = v - param<S>(p_.sigma0) * av * z[0] / g;
  zdot[0] = zd;
  Q[j_] -= param<S>(p_.sigma0) * z[0] + param<S>(p_.sigma1) * zd + param<S>(p_.sigma2) * v;
}
REFDYN_INSTANTIATE_FORCE_LAW(LuGreFriction);

}  // namespace refdyn
