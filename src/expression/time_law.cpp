#include "refdyn/expression/time_law.hpp"

#include "refdyn/common/dual.hpp"
#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>

namespace refdyn {

namespace {
bool ident_char(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

/// Positions of `name` as a variable in `text`: whole word, not followed by '(' (a call).
std::vector<size_t> identifier_positions(const std::string& text, const std::string& name) {
  std::vector<size_t> at;
  for (size_t i = 0; i + name.size() <= text.size();) {
    if (text.compare(i, name.size(), name) != 0 || (i > 0 && ident_char(text[i - 1])) ||
        (i + name.size() < text.size() && ident_char(text[i + name.size()]))) {
      // skip the whole word (a number such as 1e5 or a name containing `name`)
      if (ident_char(text[i])) {
        while (i < text.size() && ident_char(text[i])) ++i;
      } else {
        ++i;
      }
      continue;
    }
    size_t j = i + name.size();
    while (j < text.size() && std::isspace(static_cast<unsigned char>(text[j]))) ++j;
    if (j >= text.size() || text[j] != '(') at.push_back(i);
    i += name.size();
  }
  return at;
}
}  // namespace

std::string replace_identifier(const std::string& text, const std::string& name, const std::string& replacement) {
  const std::vector<size_t> at = identifier_positions(text, name);
  std::string out;
  size_t from = 0;
  for (size_t p : at) {
    out += text.substr(from, p - from) + "(" + replacement + ")";
    from = p + name.size();
  }
  return out + text.substr(from);
}

bool uses_identifier(const std::string& text, const std::string& name) {
  return !identifier_positions(text, name).empty();
}

TimeLaw::TimeLaw(Number task_duration, std::vector<Number> segments)
    : TimeLaw(TimeLawForm::segments, std::move(task_duration), std::move(segments)) {}

TimeLaw::TimeLaw(TimeLawForm form, Number task_duration, std::vector<Number> values)
    : form_(form), Tp_(std::move(task_duration)), d_(std::move(values)) {
  if (form_ == TimeLawForm::knot_speeds) {
    if (!std::isfinite(Tp_.value) || !(Tp_.value > 0))
      throw Error(expected_got("time_law task_duration", "> 0 [s]", fmt(Tp_.value)));
    if (d_.empty())
      throw Error("time_law knot_speeds: expected a list of K - 1 >= 1 task speeds > 0 at the inner knots, got an empty list");
    const size_t K = d_.size() + 1;
    const double dtau = Tp_.value / static_cast<double>(K);
    m_.assign(K + 1, 0.0);
    for (size_t i = 0; i < d_.size(); ++i) {
      if (!std::isfinite(d_[i].value) || !(d_[i].value > 0))
        throw Error(expected_got("time_law knot speed " + std::to_string(i + 1), "a task speed > 0", fmt(d_[i].value)));
      m_[i + 1] = d_[i].value;
    }
    knots_.assign(1, 0.0);
    for (size_t i = 0; i < K; ++i) knots_.push_back(knots_.back() + 2 * dtau / (m_[i] + m_[i + 1]));
    return;
  }
  if (!std::isfinite(Tp_.value) || !(Tp_.value > 0))
    throw Error(expected_got("time_law task_duration", "> 0 [s]", fmt(Tp_.value)));
  if (d_.empty()) throw Error("time_law segments: expected a list of at least one duration > 0 [s], got an empty list");
  knots_.assign(1, 0.0);
  for (size_t i = 0; i < d_.size(); ++i) {
    if (!std::isfinite(d_[i].value) || !(d_[i].value > 0))
      throw Error(expected_got("time_law segment " + std::to_string(i + 1), "a duration > 0 [s]", fmt(d_[i].value)));
    knots_.push_back(knots_.back() + d_[i].value);
  }
  const size_t K = d_.size();
  const double dtau = Tp_.value / static_cast<double>(K);
  m_.assign(K + 1, 0.0);
  for (size_t i = 1; i < K; ++i) {
    const double a = d_[i - 1].value, b = d_[i].value;
    // the three-point (parabola) slope, limited to 3·min(δ_i, δ_{i+1}) (Fritsch–Carlson)
    m_[i] = std::min(dtau * (a * a + b * b) / (a * b * (a + b)), 3.0 * dtau / std::max(a, b));
  }
}

TimeLawValue TimeLaw::eval(double t) const {
  if (t < 0) return {0, 0, 0, 0};  // at t = 0 itself: the first part (right-sided, as at every knot)
  // After the end: at rest. At t_K itself: the last part's left limit (s̈ and s⃛ of the final
  // deceleration, as at 0 the first part's), so that an integrator step ending at t_K sees one
  // smooth piece (with s̈ = 0 there, RK4's last stage saw a jump: measured 0.6 % more effort at the
  // last sample of the retimed 2R circle).
  if (t > knots_.back()) return {Tp_.value, 0, 0, 0};
  const size_t K = knots_.size() - 1;
  size_t i = static_cast<size_t>(std::upper_bound(knots_.begin(), knots_.end(), t) - knots_.begin());  // t in [t_{i-1}, t_i)
  i = std::clamp<size_t>(i, 1, K);
  if (form_ == TimeLawForm::knot_speeds) {  // constant s̈ on the part
    const double dtau = Tp_.value / static_cast<double>(K), h = t - knots_[i - 1];
    const double va = m_[i - 1], vb = m_[i], a = (vb * vb - va * va) / (2 * dtau);
    TimeLawValue v;
    v.s = t == knots_.back() ? Tp_.value : std::min(Tp_.value, dtau * static_cast<double>(i - 1) + h * (va + 0.5 * a * h));
    v.ds = t == knots_.back() ? 0.0 : va + a * h;
    v.dds = a;
    return v;
  }
  const double h = d_[i - 1].value, dtau = Tp_.value / static_cast<double>(K);
  const double u = (t - knots_[i - 1]) / h;
  const double ma = m_[i - 1] * h, mb = m_[i] * h;  // slopes in τ per unit u
  const double tau0 = dtau * static_cast<double>(i - 1);
  // s = τ_{i-1} + Δτ H01(u) + ma H10(u) + mb H11(u)
  const double H01 = u * u * (3 - 2 * u), H10 = u * (u - 1) * (u - 1), H11 = u * u * (u - 1);
  const double H01d = 6 * u * (1 - u), H10d = (3 * u - 1) * (u - 1), H11d = u * (3 * u - 2);
  const double H01dd = 6 - 12 * u, H10dd = 6 * u - 4, H11dd = 6 * u - 2;
  const double H01ddd = -12, H10ddd = 6, H11ddd = 6;
  TimeLawValue v;
  const bool end = t == knots_.back() || (i == K && u >= 1);
  v.s = end ? Tp_.value : tau0 + dtau * H01 + ma * H10 + mb * H11;
  v.ds = end ? 0.0 : (dtau * H01d + ma * H10d + mb * H11d) / h;
  v.dds = (dtau * H01dd + ma * H10dd + mb * H11dd) / (h * h);
  v.ddds = (dtau * H01ddd + ma * H10ddd + mb * H11ddd) / (h * h * h);
  return v;
}

namespace {
/// s, ṡ, s̈ on part i (1 … K) at time t over a scalar S (double or a dual number), from the part's
/// start knot t_{i−1}, the task duration Tp and the part's numbers: segments a = d_{i−1}, b = d_i,
/// c = d_{i+1} (a, c unused at the ends); knot_speeds a = v_{i−1}, b = v_i (v_0 = v_K = 0), c unused.
/// The formulas of TimeLaw::eval (file comment of time_law.hpp).
template <class S>
std::array<S, 3> part_value(TimeLawForm form, size_t i, size_t K, double t, const S& start, const S& Tp, const S& a,
                            const S& b, const S& c) {
  const S dtau = Tp / static_cast<double>(K);
  if (form == TimeLawForm::knot_speeds) {
    const S h = t - start, acc = (b * b - a * a) / (2.0 * dtau);
    return {dtau * static_cast<double>(i - 1) + h * (a + 0.5 * acc * h), a + acc * h, acc};
  }
  // the limited three-point slope of the knot between parts of durations x and y (eval's m_i)
  auto slope = [&](const S& x, const S& y) {
    const S p = dtau * (x * x + y * y) / (x * y * (x + y)), q = 3.0 * dtau / (x.v < y.v ? y : x);
    return q.v < p.v ? q : p;
  };
  const S& h = b;
  const S u = (t - start) / h;
  const S ma = i > 1 ? slope(a, b) * h : S(0.0), mb = i < K ? slope(b, c) * h : S(0.0);
  const S H01 = u * u * (3.0 - 2.0 * u), H10 = u * (u - 1.0) * (u - 1.0), H11 = u * u * (u - 1.0);
  const S H01d = 6.0 * u * (1.0 - u), H10d = (3.0 * u - 1.0) * (u - 1.0), H11d = u * (3.0 * u - 2.0);
  const S H01dd = 6.0 - 12.0 * u, H10dd = 6.0 * u - 4.0, H11dd = 6.0 * u - 2.0;
  return {dtau * static_cast<double>(i - 1) + dtau * H01 + ma * H10 + mb * H11, (dtau * H01d + ma * H10d + mb * H11d) / h,
          (dtau * H01dd + ma * H10dd + mb * H11dd) / (h * h)};
}
}  // namespace

TimeLaw::Jet TimeLaw::jet(double t) const {
  Jet j;
  j.value = eval(t);
  if (t < 0) return j;
  if (t > knots_.back()) {  // at rest at Tp
    j.theta[0] = 0;
    j.d[0][0] = 1;
    return j;
  }
  const size_t K = knots_.size() - 1;
  size_t i = static_cast<size_t>(std::upper_bound(knots_.begin(), knots_.end(), t) - knots_.begin());
  i = std::clamp<size_t>(i, 1, K);  // as eval: t in [t_{i−1}, t_i), the end in the last part
  using D = ad::Dual<5>;  // directions: t_{i−1}, Tp, a, b, c
  const bool speeds = form_ == TimeLawForm::knot_speeds;
  // the part's numbers: index into values() (−1: none, the number is 0)
  const long ia = static_cast<long>(i) - 2, ib = speeds ? (i < K ? static_cast<long>(i) - 1 : -1) : static_cast<long>(i) - 1,
             ic = !speeds && i < K ? static_cast<long>(i) : -1;
  auto number = [&](long idx, int dir) { return idx < 0 ? D(0.0) : D::variable(d_[static_cast<size_t>(idx)].value, dir); };
  const std::array<D, 3> r = part_value<D>(form_, i, K, t, D::variable(knots_[i - 1], 0), D::variable(Tp_.value, 1),
                                           number(ia, 2), number(ib, 3), number(ic, 4));
  j.knot = static_cast<int>(i) - 1;
  j.theta = {0, ia < 0 ? -1 : static_cast<int>(ia) + 1, ib < 0 ? -1 : static_cast<int>(ib) + 1,
             ic < 0 ? -1 : static_cast<int>(ic) + 1};
  for (int k = 0; k < 3; ++k) {
    j.dknot[k] = r[k].d[0];
    for (int l = 0; l < 4; ++l) j.d[k][l] = j.theta[l] < 0 ? 0.0 : r[k].d[l + 1];
  }
  return j;
}

TimeLaw::DurationJet TimeLaw::duration_jet(int i) const {
  DurationJet j;
  const size_t K = knots_.size() - 1;
  if (form_ == TimeLawForm::segments) {
    j.theta[0] = i;
    j.d[0] = 1;
    return j;
  }
  // δ_i = 2Δτ/(v_{i−1} + v_i), Δτ = Tp/K
  const double delta = knots_[static_cast<size_t>(i)] - knots_[static_cast<size_t>(i) - 1];
  const double sum = m_[static_cast<size_t>(i) - 1] + m_[static_cast<size_t>(i)];
  j.theta[0] = 0;
  j.d[0] = 2.0 / static_cast<double>(K) / sum;
  if (i > 1) j.theta[1] = i - 1, j.d[1] = -delta / sum;
  if (static_cast<size_t>(i) < K) j.theta[2] = i, j.d[2] = -delta / sum;
  return j;
}

std::vector<std::vector<double>> TimeLaw::knot_derivatives() const {
  const size_t K = knots_.size() - 1;
  std::vector<std::vector<double>> D(K + 1, std::vector<double>(d_.size() + 1, 0.0));
  for (size_t i = 1; i <= K; ++i) {
    D[i] = D[i - 1];
    const DurationJet dj = duration_jet(static_cast<int>(i));
    for (int l = 0; l < 3; ++l)
      if (dj.theta[l] >= 0) D[i][static_cast<size_t>(dj.theta[l])] += dj.d[l];
  }
  return D;
}

bool TimeLaw::has_texts() const {
  bool any = !Tp_.text.empty();
  for (const Number& d : d_) any = any || !d.text.empty();
  return any;
}

std::string TimeLaw::knot_text(size_t i) const {
  if (i == 0) return "0";
  std::string s;
  if (form_ == TimeLawForm::segments) {
    for (size_t j = 0; j < i; ++j) s += (j ? " + " : "") + symbolic_number(d_[j]);
    return "(" + s + ")";
  }
  const size_t K = d_.size() + 1;
  const std::string dtau = "(" + symbolic_number(Tp_) + "/" + std::to_string(K) + ")";
  for (size_t j = 0; j < i; ++j) {  // δ_j = 2Δτ/(v_j + v_{j+1}), v_0 = v_K = 0
    std::string den;
    if (j > 0) den = symbolic_number(d_[j - 1]);
    if (j + 1 < K) den += (den.empty() ? "" : " + ") + symbolic_number(d_[j]);
    s += (j ? " + " : "") + std::string("2*") + dtau + "/(" + den + ")";
  }
  return "(" + s + ")";
}

namespace {
/// The condition of the last part, "if(t <= t_K", taken with a relative margin of 1e-12: at the
/// law's end the value of t (the integrator's t1, the knots summed in one order) and the text of
/// t_K (summed by the compiled expression in another) may differ in the last bit, and the end
/// must be the last part's left limit either way, as the numeric law takes it (eval: s̈ of the
/// final deceleration at t_K). Without the margin the branch at t1 followed the rounding: a time
/// law's sensitivities at the final sample changed with the compiled term order (seen as columns
/// that depended on which other parameters were requested, segments form). Past t_K by less than
/// the margin the last part's polynomial differs from rest by O(margin²).
std::string last_part_condition(const std::string& knot) { return "if(t <= (1 + 1e-12)*" + knot; }
}  // namespace

std::string TimeLaw::end_text() const { return knot_text(static_cast<size_t>(segments())); }

std::string TimeLaw::symbolic_text() const {
  if (form_ == TimeLawForm::knot_speeds) {
    const size_t K = d_.size() + 1;
    const std::string dtau = "(" + symbolic_number(Tp_) + "/" + std::to_string(K) + ")";
    auto v = [&](size_t i) { return i == 0 || i == K ? std::string() : symbolic_number(d_[i - 1]); };
    std::string out = symbolic_number(Tp_);
    for (size_t i = K; i >= 1; --i) {  // part i: t in [t_{i-1}, t_i), s = τ_{i-1} + v_{i-1} u + a u²/2
      const std::string u = "(t - " + knot_text(i - 1) + ")", va = v(i - 1), vb = v(i);
      std::string seg = std::to_string(i - 1) + "*" + dtau;
      if (!va.empty()) seg += " + " + va + "*" + u;
      const std::string dv2 = vb.empty() ? "-" + va + "^2" : va.empty() ? vb + "^2" : "(" + vb + "^2 - " + va + "^2)";
      seg += " + " + dv2 + "/(4*" + dtau + ")*" + u + "^2";
      out = (i == K ? last_part_condition(knot_text(i)) : "if(t < " + knot_text(i)) + ", " + seg + ", " + out + ")";
    }
    return "if(t < 0, 0, " + out + ")";
  }
  const size_t K = d_.size();
  const std::string dtau = "(" + symbolic_number(Tp_) + "/" + std::to_string(K) + ")";
  auto knot = [&](size_t i) { return knot_text(i); };  // t_i as the sum of the durations' texts
  auto slope = [&](size_t i) {  // m_i (0 at both ends)
    if (i == 0 || i == K) return std::string("0");
    const std::string a = symbolic_number(d_[i - 1]), b = symbolic_number(d_[i]);
    return "min(" + dtau + "*(" + a + "^2 + " + b + "^2)/(" + a + "*" + b + "*(" + a + " + " + b + ")), 3*" + dtau +
           "/max(" + a + ", " + b + "))";
  };
  std::string out = symbolic_number(Tp_);
  for (size_t i = K; i >= 1; --i) {
    const std::string h = symbolic_number(d_[i - 1]);
    const std::string u = "((t - " + knot(i - 1) + ")/" + h + ")";
    std::string seg = std::to_string(i - 1) + "*" + dtau + " + " + dtau + "*" + u + "^2*(3 - 2*" + u + ")";
    if (i > 1) seg += " + " + h + "*" + slope(i - 1) + "*" + u + "*(" + u + " - 1)^2";
    if (i < K) seg += " + " + h + "*" + slope(i) + "*" + u + "^2*(" + u + " - 1)";
    out = (i == K ? last_part_condition(knot(i)) : "if(t < " + knot(i)) + ", " + seg + ", " + out + ")";
  }
  return "if(t < 0, 0, " + out + ")";
}

namespace {
thread_local bool local_form = false;  // LocalTimeLawForm alive in this thread
}  // namespace

LocalTimeLawForm::LocalTimeLawForm() : before_(local_form) { local_form = true; }
LocalTimeLawForm::~LocalTimeLawForm() { local_form = before_; }

namespace {
class Retimed final : public TimeFunction {
 public:
  Retimed(TimeFunctionPtr f, TimeLawPtr law) : f_(std::move(f)), law_(std::move(law)) {}
  TimeValue eval(double t) const override {
    const TimeLawValue s = law_->eval(t);
    const TimeValue v = f_->eval(s.s);
    return {v.f, v.df * s.ds, v.ddf * s.ds * s.ds + v.df * s.dds,
            v.dddf * s.ds * s.ds * s.ds + 3 * v.ddf * s.ds * s.dds + v.df * s.ddds};
  }
  std::string describe() const override {
    return f_->describe() + " on the time law (" + std::to_string(law_->segments()) +
           (law_->form() == TimeLawForm::knot_speeds ? " parts with knot speeds" : " segments") + ", task time " +
           fmt(law_->task_duration()) + " s in " + fmt(law_->end_time()) + " s)";
  }
  std::optional<SymbolicForm> symbolic() const override {
    std::optional<SymbolicForm> f = f_->symbolic();
    if (!f) return f;
    std::string s;
    if (local_form) {  // LocalTimeLawForm: s(t) near t_c in the four symbols, bound by the caller
      const auto& n = kTimeLawSymbols;
      const std::string u = std::string("(t - ") + n[0] + ")";
      s = std::string(n[1]) + " + " + n[2] + "*" + u + " + " + n[3] + "/2*" + u + "^2";
      for (const char* name : n) f->parameters.emplace(name, 0.0);
    } else {
      s = law_->symbolic_text();
      f->scenario_texts = f->scenario_texts || law_->has_texts();
    }
    for (std::string& row : f->rows) row = replace_identifier(row, "t", s);
    for (auto& [name, text] : f->functions) text = replace_identifier(text, "t", s);
    return f;
  }

 private:
  TimeFunctionPtr f_;
  TimeLawPtr law_;
};
}  // namespace

TimeFunctionPtr time_law_function(TimeFunctionPtr inner, TimeLawPtr law) {
  if (!inner || !law) throw Error("time_law_function: no function or no time law");
  return std::make_shared<Retimed>(std::move(inner), std::move(law));
}

}  // namespace refdyn
