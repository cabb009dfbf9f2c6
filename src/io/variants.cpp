#include "refdyn/io/variants.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/fields_json.hpp"
#include "refdyn/io/csv.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/scenario/registry.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/common/version.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>

namespace refdyn::io {

namespace fs = std::filesystem;

std::vector<Variant> expand_variants(const ScenarioSpec& spec) {
  if (!spec.variants) return {};
  const VariantsSpec& vs = *spec.variants;
  const SpecReader c = parameter_reader(spec);
  std::vector<std::string> names;
  for (const auto& p : spec.parameters) names.push_back(p.first);
  // The axes: parameters of the scenario, each varied once.
  std::vector<std::pair<std::string, std::vector<double>>> axes;
  double count = 1;
  const std::string gkey = vs.value["sweep"] ? "variants.sweep" : "variants.grid";
  const SpecValue& g = vs.value["sweep"] ? vs.value["sweep"] : vs.value["grid"];
  for (const auto& [name, values] : vs.grid) {
    const std::string key = gkey + "." + name;
    if (std::find(names.begin(), names.end(), name) == names.end())
      c.fail(g[name], key, "no parameter '" + name + "' to vary (a variant sets parameters of the scenario)" + did_you_mean(name, names));
    if (c.lists.count(name))
      c.fail(g[name], key, "'" + name + "' is a list parameter: a variant sets one number, not a list (vary a scalar parameter)");
    for (const auto& a : axes)
      if (a.first == name) c.fail(g[name], key, "the parameter '" + name + "' is varied twice");
    count *= static_cast<double>(values.size());
    axes.emplace_back(name, std::vector<double>());
  }
  long max_runs = Limits{}.max_runs;
  if (spec.limits["max_runs"])
    max_runs = static_cast<long>(std::min(c.number(spec.limits["max_runs"], "limits.max_runs"),
                                          static_cast<double>(kMaxRunsCeiling)));
  if (count > static_cast<double>(max_runs))
    c.fail(vs.value, "variants",
           fmt(count) + " variants, more than limits.max_runs = " + std::to_string(max_runs) +
               " (hint: fewer values, or raise limits.max_runs)");
  for (size_t a = 0; a < axes.size(); ++a)
    for (const SpecValue& v : vs.grid[a].second) axes[a].second.push_back(c.number(v, gkey + "." + axes[a].first));
  std::vector<Variant> out;
  std::set<std::string> seen;
  std::vector<size_t> at(axes.size(), 0);
  const SpecValue& name_at = vs.value["name"] ? vs.value["name"] : vs.value;
  for (size_t k = 0; k < static_cast<size_t>(count); ++k) {
    Variant v;
    v.name = vs.named ? vs.name : "v" + std::to_string(k);
    for (size_t a = 0; a < axes.size(); ++a) {
      v.values.emplace_back(axes[a].first, axes[a].second[at[a]]);
      if (vs.named) v.name = substitute_value(v.name, axes[a].first, axes[a].second[at[a]]);
    }
    check_output_name(c, name_at, "variants.name", v.name, "variant");
    if (!seen.insert(v.name).second)
      c.fail(name_at, "variants.name", "two variants are named '" + v.name + "' (use {parameter} in the name)");
    out.push_back(std::move(v));
    for (size_t a = axes.size(); a-- > 0;) {  // the last axis fastest
      if (++at[a] < axes[a].second.size()) break;
      at[a] = 0;
    }
  }
  return out;
}

ScenarioSpec variant_spec(const ScenarioSpec& spec, const Variant& v) {
  ScenarioSpec s = spec;
  s.variants.reset();
  for (const auto& nv : v.values) {
    auto it = std::find_if(s.parameters.begin(), s.parameters.end(), [&](const auto& p) { return p.first == nv.first; });
    if (it == s.parameters.end()) throw Error("variant '" + v.name + "': no parameter '" + nv.first + "' to set");
    // The number itself; the text (fmt: the shortest that reads back as the same double) for messages.
    s.parameter_values[nv.first] = Quantity{nv.second, fmt(nv.second), it->second.where, true};
  }
  return s;
}

namespace {

VariantSummary run_one(const ScenarioSpec& spec, const Variant& v, const VariantOptions& o) {
  VariantSummary s;
  const auto start = std::chrono::steady_clock::now();
  std::unique_ptr<Problem> p;
  try {
    p = build_problem(variant_spec(spec, v));
  } catch (const Error& e) {
    s.error = e.what();
    s.done = true;
    return s;
  }
  RunOptions ro;
  ro.track = o.track && !p->experiments.empty();
  ro.jobs = 1;  // the pool runs variants; a variant's runs run in its thread
  ro.keep_trajectories = 0;
  const fs::path dir = o.dir.empty() ? fs::path() : o.dir / v.name;
  if (!dir.empty()) {
    prepare_output_dir(dir);
    ro.run_csv_dir = dir;
  }
  const Results r = run_problem(*p, ro);
  if (!dir.empty()) {
    JsonValue summary = summary_json(*p, r);
    if (!r.runs.empty()) summary["track_csv"] = true;
    write_results(dir, *p, r, summary);
  }
  s.status = r.plan.summary.status;
  s.message = r.plan.summary.message;
  s.t_end = r.plan.summary.t_end;
  s.max_constraint_residual = r.plan.summary.max_constraint_residual;
  s.feasible = r.feasibility.feasible();
  s.violations = static_cast<long>(r.feasibility.violations.size());
  for (const auto& j : r.feasibility.joints) {
    s.peak_speed.push_back(j.peak_speed);
    s.peak_effort.push_back(j.peak_effort);
  }
  s.runs = static_cast<long>(r.runs.size());
  for (const RunRecord& run : r.runs) {
    s.runs_completed += run.summary.ok();
    s.worst_final_error = std::max(s.worst_final_error, run.summary.final_max_abs_error);
    s.worst_peak_tau = std::max(s.worst_peak_tau, run.summary.peak_abs_tau);
  }
  s.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  s.done = true;
  return s;
}

}  // namespace

std::vector<VariantSummary> run_variants(const ScenarioSpec& spec, const std::vector<Variant>& variants,
                                         const VariantOptions& o) {
  std::vector<VariantSummary> out(variants.size());
  std::function<void(size_t, size_t, size_t)> after;
  if (o.on_done) after = [&](size_t done, size_t total, size_t i) { o.on_done(done, total, variants[i].name); };
  // An exception (a folder that cannot be written, …) is not a property of a variant: it stops all.
  for_each_index(variants.size(), o.shard, o.num_shards, o.jobs,
                 [&](size_t i) { out[i] = run_one(spec, variants[i], o); }, after);
  return out;
}

namespace {

std::vector<std::string> parameter_names(const std::vector<Variant>& variants) {
  std::vector<std::string> names;
  for (const Variant& v : variants)
    for (const auto& kv : v.values)
      if (std::find(names.begin(), names.end(), kv.first) == names.end()) names.push_back(kv.first);
  return names;
}

std::string status_of(const VariantSummary& s) {
  if (!s.done) return "not_run";
  if (!s.error.empty()) return "invalid";
  return to_string(s.status);
}

double value_of(const Variant& v, const std::string& name) {
  for (const auto& [k, x] : v.values)
    if (k == name) return x;
  return std::nan("");
}

/// What the variant fields need beyond a VariantSummary: the joint names, whether runs were
/// tracked, and (per variant) whether it ran and had runs.
FieldContext variant_context(const std::vector<std::string>& joints, bool tracked, const VariantSummary* m) {
  FieldContext c;
  c.names = &joints;
  if (tracked) c.holds |= when::Tracked;
  if (m && m->done && m->error.empty()) {
    c.holds |= when::Ran;
    if (m->runs) c.holds |= when::HasRuns;
  }
  return c;
}

}  // namespace

std::string variants_csv(const std::vector<std::string>& joints, const std::vector<Variant>& variants,
                         const std::vector<VariantSummary>& summaries, bool tracked) {
  const std::vector<std::string> params = parameter_names(variants);
  std::vector<std::string> head = {"index", "name", "status"};
  head.insert(head.end(), params.begin(), params.end());
  csv_columns<VariantSummary>(head, variant_context(joints, tracked, nullptr));
  std::string s = csv_line(head);
  for (size_t i = 0; i < variants.size(); ++i) {
    const VariantSummary& m = summaries[i];
    std::vector<std::string> cells = {std::to_string(i), variants[i].name, status_of(m)};
    for (const auto& k : params) {
      const double x = value_of(variants[i], k);
      cells.push_back(std::isnan(x) ? std::string() : csv_number(x));
    }
    csv_cells(cells, m, variant_context(joints, tracked, &m));
    s += csv_line(cells);
  }
  return s;
}


JsonValue variants_summary_json(const std::string& scenario, const std::string& file,
                                const std::vector<std::string>& joints, const std::vector<Variant>& variants,
                                const std::vector<VariantSummary>& summaries, bool tracked, double wall_time) {
  JsonValue s = JsonValue::object();
  s["refdyn_version"] = version();
  s["scenario"] = scenario;
  s["file"] = file;
  s["wall_time_s"] = wall_time;
  JsonValue& vs = s["variants"] = JsonValue::array();
  long feasible = 0, valid = 0, planned = 0;
  std::vector<double> residual;
  for (size_t i = 0; i < variants.size(); ++i) {
    const VariantSummary& m = summaries[i];
    JsonValue o = JsonValue::object();
    o["name"] = variants[i].name;
    JsonValue& val = o["values"] = JsonValue::object();
    for (const auto& [k, x] : variants[i].values) val[k] = x;
    if (variants[i].sample >= 0) o["sample"] = variants[i].sample;
    o["status"] = status_of(m);
    if (!m.error.empty()) {
      o["message"] = m.error;
      residual.push_back(std::nan(""));
      vs.push_back(std::move(o));
      continue;
    }
    valid += m.done;
    planned += m.done && m.status == IntegrationStatus::Success;
    feasible += m.done && m.feasible;
    write_fields_json(o, m, variant_context(joints, tracked, &m));
    residual.push_back(m.max_constraint_residual);
    vs.push_back(std::move(o));
  }
  JsonValue& st = s["statistics"] = JsonValue::object();
  st["variants"] = static_cast<long>(variants.size());
  st["valid"] = valid;
  st["planned_to_the_end"] = planned;
  st["feasible"] = feasible;
  st["percentiles"] = "linear between order statistics (numpy default); invalid variants counted as missing";
  st["max_constraint_residual"] = distribution_json(distribution_of(residual));
  JsonValue& sj = st["joints"] = JsonValue::array();
  for (size_t j = 0; j < joints.size(); ++j) {
    std::vector<double> speed, effort;
    for (const VariantSummary& m : summaries) {
      const bool ran = m.done && m.error.empty() && j < m.peak_speed.size();
      speed.push_back(ran ? m.peak_speed[j] : std::nan(""));
      effort.push_back(ran ? m.peak_effort[j] : std::nan(""));
    }
    JsonValue& o = sj.emplace_back(JsonValue::object());
    o["joint"] = joints[j];
    o["peak_speed"] = distribution_json(distribution_of(speed));
    o["peak_effort"] = distribution_json(distribution_of(effort));
  }
  return s;
}

}  // namespace refdyn::io
