#include "kinds.hpp"

namespace refdyn::kinds {

ForceKind force_lugre() {
  ForceKind k;
  k.name = "lugre";
  k.doc = "LuGre friction in one joint with a bristle state z: ż = q̇ − σ0|q̇|z/g(q̇), τ = −(σ0 z + σ1 ż + σ2 q̇), "
          "g = μk + (μs − μk) exp(−(q̇/q̇_S)²)";
  k.keys = {{"joint", "joint", true, "", "the joint"},
            {"mu_s", "number", true, "", "static friction level μs [N m or N]"},
            {"mu_k", "number", true, "", "kinetic friction level μk [N m or N]"},
            {"sigma0", "number", true, "", "bristle stiffness σ0"},
            {"sigma1", "number", false, "0", "bristle damping σ1"},
            {"sigma2", "number", false, "0", "viscous coefficient σ2"},
            {"stribeck_velocity", "number", true, "", "Stribeck velocity q̇_S"}};
  k.build = [](const EntryArgs& a) -> NewForceElement {
    const std::string j = a.joint("joint");
    LuGreParams p;
    p.mu_s = a.number("mu_s");
    p.mu_k = a.number("mu_k");
    p.sigma0 = a.number("sigma0");
    p.sigma1 = a.number_or("sigma1", 0.0);
    p.sigma2 = a.number_or("sigma2", 0.0);
    p.v_stribeck = a.number("stribeck_velocity");
    return std::make_shared<LuGreFriction>(a.model, j, p);
  };
  return k;
}

}  // namespace refdyn::kinds
