#pragma once
// Per-joint controller gains: a list or joint: value mapping, every gain >= 0.
#include "kinds.hpp"

namespace refdyn::kinds {

inline Eigen::VectorXd gains(const EntryArgs& a, const std::string& name) {
  const Eigen::VectorXd v = a.joint_vector(name, true, 0.0);
  for (int i = 0; i < v.size(); ++i)
    if (!(v[i] >= 0))
      a.reader.fail(a.value(name), a.key(name) + "." + a.model.joint_name[i], "gains must be >= 0, got " + fmt(v[i]));
  return v;
}

}  // namespace refdyn::kinds
