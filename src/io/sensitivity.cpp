// sensitivity.csv and sensitivity.json (io/sensitivity.hpp).
#include "refdyn/io/sensitivity.hpp"

#include "refdyn/common/json.hpp"

namespace refdyn::io {

CsvTable sensitivity_table(const Problem& problem, const Plan& plan, const PlanSensitivity& s) {
  const Model& model = problem.model;
  const int n = model.nq, np = static_cast<int>(s.parameters.size());
  const int m = problem.constraints.rows();
  CsvTable table;
  table.header.push_back("t");
  for (const auto& p : s.parameters) {
    auto col = [&](const std::string& quantity) { table.header.push_back("d" + quantity + "/d" + p); };
    for (const auto& j : model.joint_name) col("q_" + j);
    for (const auto& j : model.joint_name) col("qd_" + j);
    for (const auto& z : plan.state_names) col(z);
    for (const auto& j : model.joint_name) col("qdd_" + j);
    for (const auto& j : model.joint_name) col("required_" + j);
    for (int r = 0; r < m; ++r) col("phi_" + problem.constraints.row_name(r));
  }
  for (size_t k = 0; k < s.t.size(); ++k) {
    std::vector<double> row{s.t[k]};
    for (int p = 0; p < np; ++p) {
      const Eigen::Index c = p;
      for (Eigen::Index i = 0; i < s.dx[k].rows(); ++i) row.push_back(s.dx[k](i, c));
      for (int i = 0; i < n; ++i) row.push_back(s.dqdd[k](i, c));
      for (int i = 0; i < n; ++i) row.push_back(s.deffort[k](i, c));
      for (int r = 0; r < m; ++r) row.push_back(s.dphi[k](r, c));
    }
    table.add_row(std::move(row));
  }
  return table;
}

JsonValue sensitivity_json(const Problem& problem, const PlanSensitivity& s, const std::vector<Metric>& metrics,
                           const Eigen::MatrixXd& gradients) {
  JsonValue out = JsonValue::object();
  out["scenario"] = problem.name;
  JsonValue params = JsonValue::object();
  for (const auto& p : s.parameters) params[p] = problem.parameters.at(p);
  out["parameters"] = params;
  out["maximum_rule"] =
      "a peak (max over the samples of |x|) is differentiated at its argmax sample: sign(x) dx/dp there (exact "
      "wherever the argmax is unique)";
  JsonValue list = JsonValue::array();
  for (size_t i = 0; i < metrics.size(); ++i) {
    JsonValue e = JsonValue::object();
    e["name"] = metrics[i].name;
    e["value"] = metrics[i].value;
    if (metrics[i].sample >= 0 && static_cast<size_t>(metrics[i].sample) < s.t.size())
      e["t"] = s.t[static_cast<size_t>(metrics[i].sample)];
    JsonValue g = JsonValue::object();
    for (size_t p = 0; p < s.parameters.size(); ++p)
      g[s.parameters[p]] = gradients(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(p));
    e["gradient"] = g;
    list.push_back(std::move(e));
  }
  out["metrics"] = list;
  out["wall_time_s"] = s.seconds;
  return out;
}

}  // namespace refdyn::io
