// refdyn report: report.html, one self-contained file (docs/report.md). The template
// (apps/report_template.html with three.js and dygraphs inlined at build time) is linked into
// the executable; this file fills in the data: a JSON object with the scenario summary, the
// decimated tables and the forward kinematics of every replay frame.
#include "report.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/json.hpp"
#include "refdyn/io/csv.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/common/text.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <regex>

extern "C" const char refdyn_report_template[];  // apps/CMakeLists.txt (.incbin)

namespace refdyn::app {

extern const char* const kPaperScenarioYaml;  // generated from examples/paper/paper.yaml

namespace fs = std::filesystem;

namespace {

constexpr const char* kDataMarker = "/*@@REFDYN_DATA@@*/";
constexpr const char* kSummaryMarker = "@@REFDYN_SUMMARY@@";
constexpr const char* kFeasibilityMarker = "@@REFDYN_FEASIBILITY@@";

/// JSON text that goes inside a <script> element: every '<' becomes \u003c (in valid JSON a '<'
/// can only be inside a string, where this is the same character), so neither "</script" nor
/// "<!--" can appear in it.
std::string script_safe(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (const char c : s) {
    if (c == '<') out += "\\u003c";
    else out += c;
  }
  return out;
}

/// A number in JSON with `digits` significant digits (null when not finite).
void num(std::string& out, double x, int digits = 6) {
  if (!std::isfinite(x)) {
    out += "null";
    return;
  }
  char b[32];
  std::snprintf(b, sizeof b, "%.*g", digits, x);
  out += b;
}
std::string num(double x, int digits = 17) {
  std::string s;
  num(s, x, digits);
  return s;
}

std::string str(const std::string& s) { return json_quote(s); }

/// Sample indices 0, s, 2s, ... plus the last one: at most about `n` of them.
std::vector<size_t> decimate(size_t K, int n) {
  std::vector<size_t> idx;
  if (K == 0) return idx;
  const size_t stride = std::max<size_t>(1, (K - 1 + n - 2) / std::max(1, n - 1));
  for (size_t k = 0; k < K; k += stride) idx.push_back(k);
  if (idx.back() != K - 1) idx.push_back(K - 1);
  return idx;
}

int column(const io::CsvTable& t, const std::string& name) {
  for (size_t i = 0; i < t.header.size(); ++i)
    if (t.header[i] == name) return static_cast<int>(i);
  return -1;
}

/// The rows of `t` at times `grid` by linear interpolation in its column 0 (t, increasing);
/// NaN outside its time range.
std::vector<std::vector<double>> resample(const io::CsvTable& t, const std::vector<double>& grid) {
  std::vector<std::vector<double>> out(grid.size(), std::vector<double>(t.header.size(), std::nan("")));
  const size_t K = t.rows.size();
  size_t k = 0;
  for (size_t g = 0; g < grid.size(); ++g) {
    const double tg = grid[g];
    if (K == 0 || tg < t.rows.front()[0] - 1e-12 || tg > t.rows.back()[0] + 1e-12) continue;
    while (k + 1 < K && t.rows[k + 1][0] <= tg) ++k;
    const auto& a = t.rows[k];
    if (k + 1 >= K || a[0] == tg) {
      out[g] = a;
      continue;
    }
    const auto& b = t.rows[k + 1];
    const double w = (b[0] > a[0]) ? (tg - a[0]) / (b[0] - a[0]) : 0.0;
    for (size_t c = 0; c < a.size(); ++c) out[g][c] = a[c] + w * (b[c] - a[c]);
    out[g][0] = tg;
  }
  return out;
}

/// {"columns": [...], "data": [[column values], ...]} of the rows (one array per column).
void table_json(std::string& out, const std::vector<std::string>& header, const std::vector<std::vector<double>>& rows) {
  out += "{\"columns\":[";
  for (size_t c = 0; c < header.size(); ++c) out += (c ? "," : "") + str(header[c]);
  out += "],\"data\":[";
  for (size_t c = 0; c < header.size(); ++c) {
    out += c ? ",[" : "[";
    for (size_t r = 0; r < rows.size(); ++r) {
      if (r) out += ',';
      num(out, rows[r][c], c == 0 ? 7 : 6);
    }
    out += ']';
  }
  out += "]}";
}

/// Joint coordinates of a row: the q_<joint> columns in model order.
std::vector<int> q_columns(const Model& m, const io::CsvTable& t, const std::string& what) {
  std::vector<int> cols;
  for (int j = 0; j < m.nq; ++j) {
    const int c = column(t, "q_" + m.joint_name[j]);
    if (c < 0)
      throw Error(what + ": no column q_" + m.joint_name[j] + " (the scenario '" + m.name +
                  "' does not match these results; hint: refdyn report DIR --scenario FILE)");
    cols.push_back(c);
  }
  if (t.header.empty() || t.header[0] != "t") throw Error(what + ": expected the first column to be t");
  return cols;
}

/// The forward kinematics of the rows (frames of the replay): per frame the body origins O,
/// the link-frame origins L (DH frames), the body orientations R (quaternion x, y, z, w; only
/// with `rotations`) and the model's points P, each flattened.
void kinematics_json(std::string& out, const Model& m, const std::vector<std::vector<double>>& rows,
                     const std::vector<int>& qcols, bool rotations) {
  Data data(m);
  Eigen::VectorXd q(m.nq);
  std::string O = "[", L = "[", R = "[", P = "[";
  const int nb = static_cast<int>(m.parent.size()), np = static_cast<int>(m.point_name.size());
  for (const auto& row : rows) {
    bool ok = true;
    for (int j = 0; j < m.nq; ++j) {
      q[j] = row[qcols[j]];
      ok = ok && std::isfinite(q[j]);
    }
    auto put = [&](std::string& s, const double* v, int count, int digits) {
      for (int a = 0; a < count; ++a) {
        if (s.back() != '[') s += ',';
        num(s, ok ? v[a] : std::nan(""), digits);
      }
    };
    if (ok) forward_kinematics(m, data, q);
    for (int i = 0; i < nb; ++i) {
      put(O, data.oMi[i].p.data(), 3, 7);
      const Vec3 l = link_transform(m, data, i).p;
      put(L, l.data(), 3, 7);
      if (rotations) {
        const Eigen::Quaterniond qu(data.oMi[i].R);
        const double c[4] = {qu.x(), qu.y(), qu.z(), qu.w()};
        put(R, c, 4, 5);
      }
    }
    for (int p = 0; p < np; ++p) {
      const Vec3 r = point_position(m, data, p);
      put(P, r.data(), 3, 7);
    }
  }
  out += "{\"O\":" + O + "],\"L\":" + L + "],\"P\":" + P + "]";
  if (rotations) out += ",\"R\":" + R + "]";
  out += "}";
}

/// The ellipse of a point_on_ellipse constraint, read back from its description
/// "point P on surface ((x - cx)/a)^2 + ((y - cy)/b)^2 - 1 = 0" (numbers round-trip).
bool ellipse_of(const Constraint& c, std::string& out) {
  static const std::regex re(
      R"(^point (.+) on surface \(\(x - ([^)]+)\)/([^)]+)\)\^2 \+ \(\(y - ([^)]+)\)/([^)]+)\)\^2 - 1 = 0$)");
  std::smatch m;
  const std::string d = c.describe();
  if (!std::regex_match(d, m, re)) return false;
  double v[4];
  for (int i = 0; i < 4; ++i) {
    const std::string s = m[i + 2].str();
    char* end = nullptr;
    v[i] = std::strtod(s.c_str(), &end);
    if (end == s.c_str() || *end || !std::isfinite(v[i])) return false;
  }
  out += "{\"constraint\":" + str(c.name) + ",\"point\":" + str(m[1].str()) + ",\"cx\":" + num(v[0]) +
         ",\"a\":" + num(v[1]) + ",\"cy\":" + num(v[2]) + ",\"b\":" + num(v[3]) + "}";
  return true;
}

/// The 3D view's "up": against gravity (the four-bar, gravity along −y, stands in the x-y plane);
/// +z for a model without gravity.
Vec3 view_up(const Model& m) {
  const double g = m.gravity.norm();
  if (!(g > 0 && std::isfinite(g))) return Vec3(0, 0, 1);
  return Vec3(-m.gravity / g) + Vec3::Zero();  // + 0: no "-0" in the page
}

std::string scenario_json(const Problem& p) {
  const Model& m = p.model;
  std::string o = "{\"name\":" + str(p.name) + ",\"file\":" + str(p.file);
  const Vec3 up = view_up(m);
  o += ",\"model\":{\"name\":" + str(m.name) + ",\"dof\":" + std::to_string(m.nq) + ",\"total_mass\":" +
       num(m.total_mass()) + ",\"gravity\":[" + num(m.gravity.x()) + "," + num(m.gravity.y()) + "," +
       num(m.gravity.z()) + "],\"up\":[" + num(up.x()) + "," + num(up.y()) + "," + num(up.z()) + "],\"joints\":[";
  for (int i = 0; i < m.nq; ++i) {
    const JointLimits& l = m.limits[i];
    o += std::string(i ? "," : "") + "{\"joint\":" + str(m.joint_name[i]) + ",\"body\":" + str(m.body_name[i]) +
         ",\"type\":" + str(to_string(m.joint_type[i])) + ",\"parent\":" +
         str(m.parent[i] < 0 ? std::string("base") : m.body_name[m.parent[i]]) + ",\"axis\":[" + num(m.axis[i].x(), 6) +
         "," + num(m.axis[i].y(), 6) + "," + num(m.axis[i].z(), 6) + "],\"mass\":" + num(m.inertia[i].m, 6) +
         ",\"lower\":" + num(l.lower) + ",\"upper\":" + num(l.upper) + ",\"velocity\":" + num(l.velocity) +
         ",\"effort\":" + num(l.effort) + "}";
  }
  o += "],\"points\":[";
  for (size_t i = 0; i < m.point_name.size(); ++i)
    o += std::string(i ? "," : "") + "{\"name\":" + str(m.point_name[i]) + ",\"body\":" +
         str(m.point_body[i] < 0 ? std::string("world") : m.body_name[m.point_body[i]]) + "}";
  o += "],\"parent\":[";
  for (size_t i = 0; i < m.parent.size(); ++i) o += (i ? "," : "") + std::to_string(m.parent[i]);
  o += "],\"point_body\":[";
  for (size_t i = 0; i < m.point_body.size(); ++i) o += (i ? "," : "") + std::to_string(m.point_body[i]);
  o += "]},\"constraints\":[";
  std::string ellipses;
  int k = 0;
  for (const auto& c : p.constraints.constraints()) {
    o += std::string(k++ ? "," : "") + "{\"name\":" + str(c->name) + ",\"role\":" + str(to_string(c->origin)) +
         ",\"order\":" + str(c->first_order() ? "first order (velocity)" : "holonomic (position)") +
         ",\"time\":" + str(c->rheonomic() ? "rheonomic" : "scleronomic") + ",\"rows\":" + std::to_string(c->rows()) +
         ",\"equation\":" + str(c->describe()) + "}";
    std::string e;
    if (ellipse_of(*c, e)) ellipses += (ellipses.empty() ? "" : ",") + e;
  }
  o += "],\"ellipses\":[" + ellipses + "],\"forces\":[";
  k = 0;
  for (const auto& f : p.forces.elements()) o += std::string(k++ ? "," : "") + str(f->name());
  o += "]";
  // The partition and its conditioning at t0, as `refdyn check` prints them.
  {
    auto planner = p.make_planner();
    const Eigen::VectorXd x = p.initial_state(*planner);
    Eigen::VectorXd dx(x.size());
    planner->derivative(p.integrator.t0, x, dx);
    if (const std::optional<PlannerPartition> part = planner->partition()) {
      o += ",\"partition\":{\"independent\":[";
      for (size_t i = 0; i < part->independent.size(); ++i) o += (i ? "," : "") + str(m.joint_name[part->independent[i]]);
      o += "],\"dependent\":[";
      for (size_t i = 0; i < part->dependent.size(); ++i) o += (i ? "," : "") + str(m.joint_name[part->dependent[i]]);
      o += "],\"automatic\":" + std::string(p.automatic_independent ? "true" : "false") +
           ",\"condition_t0\":" + num(part->condition) + "}";
    } else {
      o += ",\"partition\":null";  // none: the planner solves a KKT system (jerk problems)
    }
  }
  const ReferenceDynamicsOptions& ro = p.options;
  const IntegratorOptions& in = p.integrator;
  o += ",\"solver\":{\"solver\":" + str(ro.solver == ReferenceSolver::Projection ? "projection" : "lagrange") +
       ",\"baumgarte_alpha\":" + num(ro.alpha) + ",\"baumgarte_beta\":" + num(ro.beta) + ",\"beta_first_order\":" +
       num(ro.beta_first_order) + ",\"automatic_partition\":" + (ro.automatic_partition ? "true" : "false") +
       ",\"max_condition\":" + num(ro.max_condition) + ",\"integrator\":" + str(to_string(in.method)) +
       ",\"step\":" + num(in.step) + ",\"t0\":" + num(in.t0) + ",\"t1\":" + num(in.t1) +
       ",\"output_interval\":" + num(in.output_interval) + ",\"rtol\":" + num(in.rtol) + ",\"atol\":" +
       num(in.atol) + ",\"residual_from\":" + num(p.residual_from) + "}";
  o += ",\"report_points\":[";
  for (size_t i = 0; i < p.report_points.size(); ++i) o += (i ? "," : "") + str(p.report_points[i]);
  o += "],\"experiments\":[";
  for (size_t i = 0; i < p.experiments.size(); ++i) {
    const Experiment& e = *p.experiments[i];
    o += std::string(i ? "," : "") + "{\"name\":" + str(e.name) + ",\"controller\":" + str(e.controller_type) +
         ",\"plant_force_elements\":" + std::to_string(e.plant_forces.elements().size()) + ",\"sweep\":{";
    for (size_t s = 0; s < e.sweep.size(); ++s) o += (s ? "," : "") + str(e.sweep[s].first) + ":" + num(e.sweep[s].second);
    o += "}}";
  }
  o += "]}";
  return o;
}

}  // namespace

void require_report_template() {
  if (std::strncmp(refdyn_report_template, "REFDYN_REPORT_UNAVAILABLE", 25) == 0)
    throw Error("report: refdyn was built without the JavaScript libraries of the report (hint: bash "
                "scripts/install-deps.sh installs libjs-three and libjs-dygraphs; then reconfigure and rebuild)");
}

std::string report_html(const ReportInput& in) {
  require_report_template();
  const char* tpl = refdyn_report_template;
  const Problem& p = *in.problem;
  const Model& m = p.model;
  const std::vector<int> plan_q = q_columns(m, in.plan, "plan.csv");
  std::vector<std::vector<int>> run_q;
  for (const auto& [name, t] : in.runs) run_q.push_back(q_columns(m, t, "track_" + name + ".csv"));

  std::string d = "{\"version\":1,\"scenario\":" + scenario_json(p);
  // Plots: every column of plan.csv at about kReportPlotPoints samples; the runs resampled on
  // the same times (linear interpolation; RK4 runs share the plan's samples).
  const auto pidx = decimate(in.plan.rows.size(), kReportPlotPoints);
  std::vector<double> grid;
  std::vector<std::vector<double>> prow;
  for (size_t k : pidx) grid.push_back(in.plan.rows[k][0]), prow.push_back(in.plan.rows[k]);
  d += ",\"decimation\":{\"plan_samples\":" + std::to_string(in.plan.rows.size()) + ",\"plot_samples\":" +
       std::to_string(grid.size()) + "}";
  d += ",\"plot\":{\"plan\":";
  table_json(d, in.plan.header, prow);
  d += ",\"runs\":[";
  for (size_t r = 0; r < in.runs.size(); ++r) {
    d += (r ? ",{" : "{") + std::string("\"name\":") + str(in.runs[r].first) + ",\"table\":";
    table_json(d, in.runs[r].second.header, resample(in.runs[r].second, grid));
    d += "}";
  }
  d += "]}";
  // Replay: forward kinematics at about kReportReplayFrames frames.
  const auto ridx = decimate(in.plan.rows.size(), kReportReplayFrames);
  std::vector<double> rgrid;
  std::vector<std::vector<double>> rrow;
  for (size_t k : ridx) rgrid.push_back(in.plan.rows[k][0]), rrow.push_back(in.plan.rows[k]);
  d += ",\"replay\":{\"t\":[";
  for (size_t k = 0; k < rgrid.size(); ++k) {
    if (k) d += ',';
    num(d, rgrid[k], 7);
  }
  d += "],\"plan\":";
  kinematics_json(d, m, rrow, plan_q, true);
  d += ",\"runs\":[";
  for (size_t r = 0; r < in.runs.size(); ++r) {
    d += (r ? ",{" : "{") + std::string("\"name\":") + str(in.runs[r].first) + ",\"frames\":";
    kinematics_json(d, m, resample(in.runs[r].second, rgrid), run_q[r], false);
    d += "}";
  }
  d += "]}}";

  // The markers are located in the template once, so nothing inserted can be taken for one.
  const std::string t = tpl;
  std::vector<std::pair<size_t, std::pair<std::string, std::string>>> parts;
  for (const auto& [marker, text] : {std::pair<std::string, std::string>{kSummaryMarker, script_safe(in.summary_json)},
                                     {kFeasibilityMarker, script_safe(in.feasibility_json)},
                                     {kDataMarker, script_safe(d)}}) {
    const size_t at = t.find(marker);
    if (at == std::string::npos) throw std::logic_error("report template: marker " + marker + " missing");
    parts.push_back({at, {marker, text}});
  }
  std::sort(parts.begin(), parts.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::string html;
  html.reserve(t.size() + d.size() + in.summary_json.size() + in.feasibility_json.size() + 64);
  size_t from = 0;
  for (const auto& [at, mt] : parts) {
    html.append(t, from, at - from);
    html += mt.second;
    from = at + mt.first.size();
  }
  html.append(t, from, std::string::npos);
  return html;
}

void write_report(const fs::path& dir, const Problem& problem, const io::Results& r, const JsonValue& summary) {
  ReportInput in;
  in.problem = &problem;
  in.summary_json = json_text(summary, 2, 2);
  in.feasibility_json = r.feasibility.json();
  in.plan = io::trajectory_table(r.plan);
  for (const auto& run : r.runs)  // the runs whose trajectories were kept (RunOptions::keep_trajectories)
    if (in.runs.size() < kReportMaxRuns && !run.result.joints.empty())
      in.runs.emplace_back(run.experiment->name, io::trajectory_table(run.result));
  const std::string html = report_html(in);
  io::write_text_atomic(dir / "report.html", html);
}

int run_report(const std::string& dir_name, const std::string& scenario, const std::string& output, bool quiet,
               const InputOptions& opt) {
  const fs::path dir(dir_name);
  if (!fs::is_directory(dir))
    throw Error("results folder '" + dir_name + "': not found (hint: run refdyn plan/track/paper first)");
  for (const char* f : {"plan.csv", "summary.json", "feasibility.json"})
    if (!fs::exists(dir / f))
      throw Error("results folder '" + dir_name + "': no " + f + " in it (hint: point to a folder written by refdyn plan/track/paper)");
  ReportInput in;
  // As written by write_results: the JSON text plus a newline (dropped: the report of a results
  // folder is byte-for-byte the one `--report` wrote with it).
  auto json_file = [&](const char* name) {
    std::string s = io::read_text_file((dir / name).string(), "results file");
    if (!s.empty() && s.back() == '\n') s.pop_back();
    return s;
  };
  in.summary_json = json_file("summary.json");
  in.feasibility_json = json_file("feasibility.json");
  const JsonValue summary = parse_json(in.summary_json, (dir / "summary.json").string());
  auto text_member = [&](const char* key) {
    const auto it = summary.find(key);
    return it != summary.end() && it->is_string() ? it->get<std::string>() : std::string();
  };
  std::unique_ptr<Problem> problem;
  if (!scenario.empty()) {
    problem = io::load_problem(scenario, opt.max_input_bytes);
  } else if (text_member("study") == "paper three-link manipulator") {
    problem = io::parse_problem(kPaperScenarioYaml, "examples/paper/paper.yaml");
  } else {
    const std::string file = text_member("file");
    if (file.empty())
      throw Error("results folder '" + dir_name + "': summary.json names no scenario file (hint: --scenario FILE)");
    if (!fs::exists(file))
      throw Error("scenario file '" + file + "' (named in " + (dir / "summary.json").string() +
                  "): not found from here (hint: --scenario FILE)");
    problem = io::load_problem(file, opt.max_input_bytes);
  }
  in.problem = problem.get();
  in.plan = io::read_csv_numbers((dir / "plan.csv").string());
  // The runs summary.json lists, in its order (not whatever track_*.csv an older run left).
  // The first kReportMaxRuns of them; none when the run CSVs were not written (--run-csv none).
  const auto track_csv = summary.find("track_csv");
  const bool run_csv = track_csv == summary.end() || !track_csv->is_boolean() || track_csv->get<bool>();
  const auto runs = summary.find("runs");
  if (run_csv && runs != summary.end() && runs->is_array())
    for (const JsonValue& run : *runs) {
      if (in.runs.size() >= kReportMaxRuns) break;
      const auto label = run.find("label");
      if (label == run.end() || !label->is_string()) continue;
      const std::string name = label->get<std::string>();
      // Experiment names are file-safe (check_output_name); anything else is not a run of ours.
      if (name.empty() || name.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._+=-") !=
                              std::string::npos)
        continue;
      const fs::path f = dir / ("track_" + name + ".csv");
      if (!fs::exists(f))
        throw Error("results folder '" + dir_name + "': summary.json lists the run '" + name + "' but there is no " +
                    f.filename().string());
      in.runs.emplace_back(name, io::read_csv_numbers(f.string()));
    }
  const std::string html = report_html(in);  // everything is formed before anything is written
  const fs::path out = output.empty() ? dir / "report.html" : fs::path(output);
  io::write_text_atomic(out, html);
  if (!quiet) std::printf("report: %s (%.2f MB)\n", out.c_str(), html.size() / 1e6);
  return kOk;
}

}  // namespace refdyn::app
