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
#include <cctype>
#include <cmath>
#include <limits>
#include <map>
#include <cstdio>
#include <cstdlib>
#include <cstring>

extern "C" const char refdyn_report_template[];  // apps/CMakeLists.txt (.incbin)

namespace refdyn::app {

extern const char* const kPaperScenarioYaml;  // generated from examples/paper/paper.yaml

namespace fs = std::filesystem;

namespace {

constexpr const char* kDataMarker = "/*@@REFDYN_DATA@@*/";
constexpr const char* kSummaryMarker = "@@REFDYN_SUMMARY@@";
constexpr const char* kFeasibilityMarker = "@@REFDYN_FEASIBILITY@@";
/// Around the three.js mesh loaders (apps/report_template.cmake): kept only in a page with meshes.
constexpr const char* kLoadersBegin = "/*@@REFDYN_LOADERS_BEGIN@@*/";
constexpr const char* kLoadersEnd = "/*@@REFDYN_LOADERS_END@@*/";

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

/// A JSON number with `digits` significant digits (null when not finite): the double nearest
/// the rounded decimal, which json_text writes as that decimal (shortest round trip).
JsonValue num(double x, int digits = 6) {
  if (!std::isfinite(x)) return JsonValue();
  char b[32];
  std::snprintf(b, sizeof b, "%.*g", digits, x);
  return JsonValue(std::strtod(b, nullptr));
}

JsonValue strings(const std::vector<std::string>& v) {
  JsonValue a = JsonValue::array();
  for (const auto& x : v) a.push_back(x);
  return a;
}

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
JsonValue table_json(const std::vector<std::string>& header, const std::vector<std::vector<double>>& rows) {
  JsonValue data = JsonValue::array();
  for (size_t c = 0; c < header.size(); ++c) {
    JsonValue col = JsonValue::array();
    for (const auto& r : rows) col.push_back(num(r[c], c == 0 ? 7 : 6));
    data.push_back(std::move(col));
  }
  JsonValue o = JsonValue::object();
  o["columns"] = strings(header);
  o["data"] = std::move(data);
  return o;
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
JsonValue kinematics_json(const Model& m, const std::vector<std::vector<double>>& rows, const std::vector<int>& qcols,
                          bool rotations) {
  Data data(m);
  Eigen::VectorXd q(m.nq);
  JsonValue O = JsonValue::array(), L = JsonValue::array(), R = JsonValue::array(), P = JsonValue::array();
  const int nb = static_cast<int>(m.parent.size()), np = static_cast<int>(m.point_name.size());
  for (const auto& row : rows) {
    bool ok = true;
    for (int j = 0; j < m.nq; ++j) {
      q[j] = row[qcols[j]];
      ok = ok && std::isfinite(q[j]);
    }
    auto put = [&](JsonValue& a, const double* v, int count, int digits) {
      for (int k = 0; k < count; ++k) a.push_back(num(ok ? v[k] : std::nan(""), digits));
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
  JsonValue o = JsonValue::object();
  o["O"] = std::move(O);
  o["L"] = std::move(L);
  o["P"] = std::move(P);
  if (rotations) o["R"] = std::move(R);
  return o;
}

/// The 3D view's "up": against gravity (the four-bar, gravity along −y, stands in the x-y plane);
/// +z for a model without gravity.
Vec3 view_up(const Model& m) {
  const double g = m.gravity.norm();
  if (!(g > 0 && std::isfinite(g))) return Vec3(0, 0, 1);
  return Vec3(-m.gravity / g) + Vec3::Zero();  // + 0: no "-0" in the page
}

JsonValue vec_json(const Vec3& v, int digits) {
  JsonValue a = JsonValue::array();
  for (int k = 0; k < 3; ++k) a.push_back(num(v[k], digits));
  return a;
}

JsonValue model_json(const Model& m) {
  JsonValue o = JsonValue::object();
  o["name"] = m.name;
  o["dof"] = m.nq;
  o["total_mass"] = num(m.total_mass(), 17);
  o["gravity"] = vec_json(m.gravity, 17);
  o["up"] = vec_json(view_up(m), 17);
  JsonValue& joints = o["joints"] = JsonValue::array();
  for (int i = 0; i < m.nq; ++i) {
    const JointLimits& l = m.limits[i];
    JsonValue j = JsonValue::object();
    j["joint"] = m.joint_name[i];
    j["body"] = m.body_name[i];
    j["type"] = to_string(m.joint_type[i]);
    j["parent"] = m.parent[i] < 0 ? std::string("base") : m.body_name[m.parent[i]];
    j["axis"] = vec_json(m.axis[i], 6);
    j["mass"] = num(m.inertia[i].m, 6);
    j["lower"] = num(l.lower, 17);
    j["upper"] = num(l.upper, 17);
    j["velocity"] = num(l.velocity, 17);
    j["effort"] = num(l.effort, 17);
    joints.push_back(std::move(j));
  }
  JsonValue& points = o["points"] = JsonValue::array();
  for (size_t i = 0; i < m.point_name.size(); ++i) {
    JsonValue pt = JsonValue::object();
    pt["name"] = m.point_name[i];
    pt["body"] = m.point_body[i] < 0 ? std::string("world") : m.body_name[m.point_body[i]];
    points.push_back(std::move(pt));
  }
  o["parent"] = m.parent;
  o["point_body"] = m.point_body;
  return o;
}

/// RFC 4648 base64 of `bytes`.
std::string base64(const std::string& bytes) {
  static const char* A = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = static_cast<unsigned char>(bytes[i]) << 16 | static_cast<unsigned char>(bytes[i + 1]) << 8 |
                       static_cast<unsigned char>(bytes[i + 2]);
    for (int k = 18; k >= 0; k -= 6) out += A[(v >> k) & 63];
  }
  if (i < bytes.size()) {
    const bool two = i + 1 < bytes.size();
    const unsigned v = static_cast<unsigned char>(bytes[i]) << 16 | (two ? static_cast<unsigned char>(bytes[i + 1]) << 8 : 0);
    out += A[(v >> 18) & 63];
    out += A[(v >> 12) & 63];
    out += two ? A[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

/// "stl", "dae" or "obj" from a file name (any case); "" for another format.
std::string mesh_format(const std::string& file) {
  std::string e = fs::path(file).extension().string();
  for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e == ".stl" || e == ".dae" || e == ".obj" ? e.substr(1) : std::string();
}

/// The model's visual geometry for the replay (Problem::visuals, on the link frames of the model):
/// {meshes: [{format, file, data (base64)}], items: [{link, body, p, q, shape, mesh | size |
/// radius, length, scale, color}], bytes, budget, fallback, notes}. Meshes that cannot be drawn
/// (unresolved, unreadable, another format) are left out with a note; above the budget every
/// mesh is, and the replay draws segments (fallback).
JsonValue visuals_json(const Problem& p, double budget, std::vector<std::string>& notes) {
  const Model& m = p.model;
  JsonValue meshes = JsonValue::array(), items = JsonValue::array();
  std::map<std::string, int> mesh_index;
  std::vector<std::string> data;
  double bytes = 0;
  int missing = 0;
  for (const VisualSpec& v : p.visuals) {
    const auto f = std::find(m.frame_name.begin(), m.frame_name.end(), v.link);
    if (f == m.frame_name.end()) continue;  // a link outside the model (not loaded)
    const int fi = static_cast<int>(f - m.frame_name.begin());
    const SE3 X = m.frame_pose[fi] * v.origin;  // in the body frame (the world's for body −1)
    JsonValue it = JsonValue::object();
    it["link"] = v.link;
    it["body"] = m.frame_body[fi];
    it["p"] = vec_json(X.p, 9);
    const Eigen::Quaterniond qu(X.R);
    it["q"] = JsonValue::array({num(qu.x(), 9), num(qu.y(), 9), num(qu.z(), 9), num(qu.w(), 9)});
    if (v.has_color) it["color"] = JsonValue::array({num(v.rgba[0], 4), num(v.rgba[1], 4), num(v.rgba[2], 4), num(v.rgba[3], 4)});
    switch (v.shape) {
      case VisualSpec::Shape::Mesh: {
        std::string why = v.note;
        const std::string format = mesh_format(v.uri);
        if (why.empty() && format.empty()) why = "not an STL, COLLADA or OBJ file";
        if (why.empty() && mesh_index.find(v.file) == mesh_index.end()) {
          std::string content;
          try {
            content = io::read_text_file(v.file, "mesh file", std::numeric_limits<std::size_t>::max());
          } catch (const Error&) {
            why = "cannot read " + v.file;
          }
          if (why.empty()) {
            mesh_index[v.file] = static_cast<int>(data.size());
            data.push_back(base64(content));
            bytes += static_cast<double>(data.back().size());
            JsonValue mj = JsonValue::object();
            mj["format"] = format;
            mj["file"] = v.uri;
            meshes.push_back(std::move(mj));
          }
        }
        if (!why.empty()) {
          ++missing;
          notes.push_back("link " + v.link + ": mesh " + v.uri + " not drawn: " + why);
          continue;
        }
        it["shape"] = "mesh";
        it["mesh"] = mesh_index[v.file];
        it["scale"] = vec_json(v.size, 9);
        break;
      }
      case VisualSpec::Shape::Box:
        it["shape"] = "box";
        it["size"] = vec_json(v.size, 9);
        break;
      case VisualSpec::Shape::Cylinder:
        it["shape"] = "cylinder";
        it["radius"] = num(v.radius, 9);
        it["length"] = num(v.length, 9);
        break;
      case VisualSpec::Shape::Sphere:
        it["shape"] = "sphere";
        it["radius"] = num(v.radius, 9);
        break;
    }
    items.push_back(std::move(it));
  }
  const bool fallback = bytes > budget;
  if (fallback) {
    char b[256];
    std::snprintf(b, sizeof b,
                  "the URDF's meshes (%.3g MB inlined) exceed the report's budget of %.3g MB: the 3D replay draws the "
                  "links as segments (refdyn report DIR --mesh-budget %.0f draws them)",
                  bytes / 1e6, budget / 1e6, std::ceil(bytes / 1e6));
    notes.push_back(b);
  } else {
    for (size_t k = 0; k < data.size(); ++k) meshes[k]["data"] = std::move(data[k]);
  }
  JsonValue o = JsonValue::object();
  o["meshes"] = fallback ? JsonValue::array() : std::move(meshes);
  o["items"] = fallback ? JsonValue::array() : std::move(items);
  o["bytes"] = bytes;
  o["budget"] = budget;
  o["fallback"] = fallback;
  o["missing"] = missing;
  o["notes"] = strings(notes);
  return o;
}

/// The constraints as built (name, role, order, time dependence, equation) and the task
/// geometry they record (the ellipses of point_on_ellipse constraints, for the 3D view).
void constraints_json(const Problem& p, JsonValue& o) {
  // (Locals, assigned at the end: a reference into an ordered_json object is invalidated by the
  // next member added to it.)
  JsonValue cs = JsonValue::array(), ellipses = JsonValue::array();
  for (const auto& c : p.constraints.constraints()) {
    JsonValue r = JsonValue::object();
    r["name"] = c->name;
    r["role"] = to_string(c->origin);
    r["order"] = order_label(c->order());
    r["time"] = c->rheonomic() ? "rheonomic" : "scleronomic";
    r["rows"] = c->rows();
    r["equation"] = c->describe();
    cs.push_back(std::move(r));
    if (const std::optional<TaskGeometry> g = c->geometry(); g && g->kind == "ellipse") {
      JsonValue e = JsonValue::object();
      e["constraint"] = c->name;
      e["point"] = g->point;
      for (const char* k : {"cx", "a", "cy", "b"}) e[k] = num(g->value(k), 17);
      ellipses.push_back(std::move(e));
    }
  }
  o["constraints"] = std::move(cs);
  o["ellipses"] = std::move(ellipses);
}

/// The partition recorded in summary.json (plan.partition_t0, written when the plan was made);
/// null for a KKT planner or results of a refdyn that did not record it.
JsonValue recorded_partition(const JsonValue& summary) {
  const auto plan = summary.find("plan");
  if (plan == summary.end() || !plan->is_object()) return JsonValue();
  const auto part = plan->find("partition_t0");
  if (part == plan->end() || !part->is_object()) return JsonValue();
  JsonValue o = JsonValue::object();
  for (const char* k : {"independent", "dependent", "automatic", "used_by_solver"}) o[k] = part->value(k, JsonValue());
  o["condition_t0"] = part->value("condition", JsonValue());
  return o;
}

JsonValue solver_json(const Problem& p) {
  const ReferenceDynamicsOptions& ro = p.options;
  const IntegratorOptions& in = p.integrator;
  JsonValue o = JsonValue::object();
  o["solver"] = ro.solver == ReferenceSolver::Projection ? "projection" : "lagrange";
  o["baumgarte_alpha"] = num(ro.alpha, 17);
  o["baumgarte_beta"] = num(ro.beta, 17);
  o["beta_first_order"] = num(ro.beta_first_order, 17);
  // How the partition was chosen (partition.independent: auto, as summary.json's "automatic")
  // and whether it is re-chosen when κ exceeds max_condition (partition.automatic_switch).
  o["partition_automatic"] = p.automatic_independent;
  o["partition_switch"] = ro.automatic_partition;
  o["max_condition"] = num(ro.max_condition, 17);
  o["integrator"] = to_string(in.method);
  for (const auto& [k, v] : {std::pair<const char*, double>{"step", in.step}, {"t0", in.t0}, {"t1", in.t1},
                             {"output_interval", in.output_interval}, {"rtol", in.rtol}, {"atol", in.atol},
                             {"residual_from", p.residual_from}})
    o[k] = num(v, 17);
  return o;
}

JsonValue experiments_json(const Problem& p) {
  JsonValue a = JsonValue::array();
  for (const auto& e : p.experiments) {
    JsonValue o = JsonValue::object();
    o["name"] = e->name;
    o["controller"] = e->controller_type;
    o["plant_force_elements"] = static_cast<int>(e->plant_forces.elements().size());
    JsonValue& sw = o["sweep"] = JsonValue::object();
    for (const auto& [k, v] : e->sweep) sw[k] = num(v, 17);
    a.push_back(std::move(o));
  }
  return a;
}

/// The scenario part of the page: what the problem recorded when it was built, and the
/// partition summary.json recorded when the plan was made (nothing is re-run).
JsonValue scenario_json(const Problem& p, const JsonValue& summary, double mesh_budget, std::vector<std::string>& notes) {
  JsonValue o = JsonValue::object();
  o["name"] = p.name;
  o["file"] = p.file;
  o["model"] = model_json(p.model);
  if (!p.visuals.empty()) o["visuals"] = visuals_json(p, mesh_budget, notes);
  constraints_json(p, o);
  JsonValue& forces = o["forces"] = JsonValue::array();
  for (const auto& f : p.forces.elements()) forces.push_back(f->name());
  o["partition"] = recorded_partition(summary);
  o["solver"] = solver_json(p);
  o["report_points"] = strings(p.report_points);
  o["experiments"] = experiments_json(p);
  return o;
}

}  // namespace

void require_report_template() {
  if (std::strncmp(refdyn_report_template, "REFDYN_REPORT_UNAVAILABLE", 25) == 0)
    throw Error("report: refdyn was built without the JavaScript libraries of the report (hint: bash "
                "scripts/install-deps.sh installs libjs-three and libjs-dygraphs; then reconfigure and rebuild)");
}

std::string report_html(const ReportInput& in, std::vector<std::string>* notes_out) {
  require_report_template();
  const char* tpl = refdyn_report_template;
  const Problem& p = *in.problem;
  const Model& m = p.model;
  const std::vector<int> plan_q = q_columns(m, in.plan, "plan.csv");
  std::vector<std::vector<int>> run_q;
  for (const auto& [name, t] : in.runs) run_q.push_back(q_columns(m, t, "track_" + name + ".csv"));

  JsonValue data = JsonValue::object();
  data["version"] = 1;
  std::vector<std::string> notes;
  data["scenario"] = scenario_json(p, parse_json(in.summary_json, "summary.json"), in.mesh_budget, notes);
  const JsonValue& sc = data["scenario"];
  const bool meshes_drawn = sc.contains("visuals") && !sc["visuals"]["items"].empty();
  if (notes_out) *notes_out = notes;
  // Plots: every column of plan.csv at about kReportPlotPoints samples; the runs resampled on
  // the same times (linear interpolation; RK4 runs share the plan's samples).
  const auto pidx = decimate(in.plan.rows.size(), kReportPlotPoints);
  std::vector<double> grid;
  std::vector<std::vector<double>> prow;
  for (size_t k : pidx) grid.push_back(in.plan.rows[k][0]), prow.push_back(in.plan.rows[k]);
  data["decimation"] = {{"plan_samples", in.plan.rows.size()}, {"plot_samples", grid.size()}};
  JsonValue& plot = data["plot"] = JsonValue::object();
  plot["plan"] = table_json(in.plan.header, prow);
  JsonValue& plot_runs = plot["runs"] = JsonValue::array();
  for (const auto& [name, table] : in.runs)
    plot_runs.push_back({{"name", name}, {"table", table_json(table.header, resample(table, grid))}});
  // Replay: forward kinematics at about kReportReplayFrames frames.
  const auto ridx = decimate(in.plan.rows.size(), kReportReplayFrames);
  std::vector<double> rgrid;
  std::vector<std::vector<double>> rrow;
  for (size_t k : ridx) rgrid.push_back(in.plan.rows[k][0]), rrow.push_back(in.plan.rows[k]);
  JsonValue& replay = data["replay"] = JsonValue::object();
  JsonValue& rt = replay["t"] = JsonValue::array();
  for (double t : rgrid) rt.push_back(num(t, 7));
  replay["plan"] = kinematics_json(m, rrow, plan_q, true);
  JsonValue& replay_runs = replay["runs"] = JsonValue::array();
  for (size_t r = 0; r < in.runs.size(); ++r)
    replay_runs.push_back(
        {{"name", in.runs[r].first}, {"frames", kinematics_json(m, resample(in.runs[r].second, rgrid), run_q[r], false)}});
  if (!in.optimization.header.empty()) {
    // The numeric columns (index … feasible; not status and reason); "nan" cells as null.
    const auto& h = in.optimization.header;
    const int last = in.optimization.column("feasible");
    if (in.optimization.column("index") != 0 || in.optimization.column("objective") < 0 || last < 0)
      throw Error("optimization.csv: expected the columns index, the variables, objective, the constraints, feasible, …");
    JsonValue o = JsonValue::object();
    o["columns"] = JsonValue(std::vector<std::string>(h.begin(), h.begin() + last + 1));
    JsonValue rows = JsonValue::array();
    for (const auto& r : in.optimization.rows) {
      JsonValue row = JsonValue::array();
      for (int c = 0; c <= last; ++c) {
        char* end = nullptr;
        const double v = std::strtod(r[static_cast<size_t>(c)].c_str(), &end);
        if (std::isfinite(v) && end && *end == 0) row.push_back(v);
        else row.push_back(nullptr);
      }
      rows.push_back(row);
    }
    o["rows"] = rows;
    const JsonValue summary = parse_json(in.summary_json, "summary.json");
    const auto opt = summary.find("optimization");
    if (opt != summary.end() && opt->is_object()) {
      if (opt->contains("method")) o["method"] = (*opt)["method"];
      o["maximize"] = opt->contains("sense") && (*opt)["sense"] == "maximize";
    } else {
      o["maximize"] = false;
    }
    data["optimization"] = o;
  }
  const std::string d = json_text(data, -1);  // minimal separators: the page is large

  // The markers are located in the template once, so nothing inserted can be taken for one. The
  // three.js mesh loaders are in the page only when it draws meshes.
  std::string t = tpl;
  const size_t lb = t.find(kLoadersBegin), le = t.find(kLoadersEnd);
  if (lb == std::string::npos || le == std::string::npos || le < lb)
    throw std::logic_error("report template: the mesh loaders' markers are missing");
  if (meshes_drawn) t.erase(le, std::strlen(kLoadersEnd)), t.erase(lb, std::strlen(kLoadersBegin));
  else t.erase(lb, le + std::strlen(kLoadersEnd) - lb);
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

namespace {
/// The notes of a report on the terminal: the first three, then how many more the page has.
void print_notes(const std::vector<std::string>& notes) {
  for (size_t k = 0; k < notes.size() && k < 3; ++k) std::fprintf(stderr, "report: note: %s\n", notes[k].c_str());
  if (notes.size() > 3) std::fprintf(stderr, "report: ... %zu more notes in the page (3D replay)\n", notes.size() - 3);
}

}  // namespace

void write_report(const fs::path& dir, const Problem& problem, const io::Results& r, const JsonValue& summary,
                  bool quiet) {
  ReportInput in;
  in.problem = &problem;
  in.summary_json = json_text(summary, 2, 2);
  in.feasibility_json = r.feasibility.json();
  in.plan = io::trajectory_table(r.plan);
  for (const auto& run : r.runs)  // the runs whose trajectories were kept (RunOptions::keep_trajectories)
    if (in.runs.size() < kReportMaxRuns && !run.result.joints.empty())
      in.runs.emplace_back(run.experiment->name, io::trajectory_table(run.result));
  std::vector<std::string> notes;
  const std::string html = report_html(in, &notes);
  io::write_text_atomic(dir / "report.html", html);
  if (!quiet) print_notes(notes);
}

int run_report(const std::string& dir_name, const std::string& scenario, const std::string& output, bool quiet,
               const InputOptions& opt, double mesh_budget_mb) {
  if (!(mesh_budget_mb >= 0) || !std::isfinite(mesh_budget_mb))
    throw Error("--mesh-budget: expected a number of MB >= 0, got " + fmt(mesh_budget_mb));
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
  if (fs::exists(dir / "optimization.csv")) {
    const std::string f = (dir / "optimization.csv").string();
    in.optimization = io::parse_csv(io::read_text_file(f, "results file"), f);
  }
  in.mesh_budget = mesh_budget_mb * 1e6;
  std::vector<std::string> notes;
  const std::string html = report_html(in, &notes);  // everything is formed before anything is written
  const fs::path out = output.empty() ? dir / "report.html" : fs::path(output);
  io::write_text_atomic(out, html);
  if (!quiet) {
    std::printf("report: %s (%.2f MB)\n", out.c_str(), html.size() / 1e6);
    print_notes(notes);
  }
  return kOk;
}

}  // namespace refdyn::app
