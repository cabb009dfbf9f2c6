#pragma once
// Per-joint controller gains: a list or joint: value mapping, every gain >= 0, on the joints the
// controller assigns (`assigned`: every joint for an unconstrained plant with a motor at each
// joint; else the plant's independent coordinates or its motors, docs/scenario.md "The plant").
#include "kinds.hpp"

#include <algorithm>
#include <limits>

namespace refdyn::kinds {

/// `what` says which joints these are ("the coordinates it assigns", "its motors"), for messages.
inline Eigen::VectorXd gains(const EntryArgs& a, const std::string& name, const std::vector<int>* assigned = nullptr,
                             const std::string& what = "") {
  const Model& m = a.model;
  if (!assigned || static_cast<int>(assigned->size()) == m.nv) {  // every joint: as ever
    const Eigen::VectorXd v = a.joint_vector(name, true, 0.0);
    for (int i = 0; i < v.size(); ++i)
      if (!(v[i] >= 0)) a.reader.fail(a.value(name), a.key(name) + "." + m.joint_name[i], "gains must be >= 0, got " + fmt(v[i]));
    return v;
  }
  const std::string list = Actuation::names(m, *assigned);
  const SpecValue& val = a.value(name);
  Eigen::VectorXd v = Eigen::VectorXd::Zero(m.nv);
  if (val.is_list()) {  // the assigned joints' gains, in joint order
    if (val.size() != assigned->size())
      a.reader.fail(val, a.key(name), "expected " + std::to_string(assigned->size()) + " values (one per joint of " +
                                          what + ": " + list + "), got " + std::to_string(val.size()));
    for (size_t i = 0; i < assigned->size(); ++i)
      v[(*assigned)[i]] = a.reader.number(val[i], a.key(name) + "[" + std::to_string(i) + "]");
  } else {
    const Eigen::VectorXd given = a.joint_vector(name, false, std::numeric_limits<double>::quiet_NaN());
    auto mine = [&](int j) { return std::find(assigned->begin(), assigned->end(), j) != assigned->end(); };
    for (int j = 0; j < m.nv; ++j)  // a gain where there is none to give first: the likelier mistake
      if (!std::isnan(given[j]) && !mine(j))
        a.reader.fail(val, a.key(name) + "." + m.joint_name[j],
                      "a gain on '" + m.joint_name[j] + "', which this controller does not assign (it assigns " + what +
                          ": " + list + ")");
    for (int j : *assigned) {
      if (std::isnan(given[j]))
        a.reader.fail(val, a.key(name), "missing a value for joint '" + m.joint_name[j] + "' (give one for each of " +
                                            what + ": " + list + ")");
      v[j] = given[j];
    }
  }
  for (int j : *assigned)
    if (!(v[j] >= 0)) a.reader.fail(val, a.key(name) + "." + m.joint_name[j], "gains must be >= 0, got " + fmt(v[j]));
  return v;
}

/// The plant the controller is built for (every joint a motor, no material rows when not given).
inline Actuation actuation_of(const EntryArgs& a) { return a.actuation ? *a.actuation : Actuation::full(a.model); }

}  // namespace refdyn::kinds
