#pragma once
/// A time law s(t): real time t → task time τ = s(t) (the scenario's `time_law:` section,
/// docs/scenario.md "time_law"). The task's span [0, Tp] is cut into K equal parts of task time
/// Δτ = Tp/K; part i takes d_i seconds of real time. s is the piecewise cubic Hermite
/// interpolant through the knots (t_i, τ_i), t_i = d_1 + … + d_i, τ_i = i·Tp/K, with knot slopes
///   m_0 = m_K = 0 (rest to rest),
///   m_i = min(Δτ (d_i² + d_{i+1}²)/(d_i d_{i+1} (d_i + d_{i+1})), 3Δτ/max(d_i, d_{i+1}))  (0 < i < K):
/// the slope of the parabola through the three neighbouring knots (exact for a constant
/// acceleration, so a bang-bang law is reproduced well), limited to 3·min(δ_i, δ_{i+1}) with the
/// secants δ_i = Δτ/d_i (Fritsch–Carlson). Since then m_{i−1}/δ_i ≤ 3 and m_i/δ_i ≤ 3 on every part
/// (inside Fritsch–Carlson's monotone region), s is monotone and C¹ by construction,
/// s(0) = 0, s(Σd) = Tp exactly; s = 0 before 0 and s = Tp
/// after Σd. s̈ and s⃛ are piecewise (s̈ may jump at the knots; at a knot the part after it is
/// taken, except at the end Σd, where the last part's left limit is: the final deceleration).
///
/// The second form (TimeLawForm::knot_speeds, `time_law: {task_duration, knot_speeds}`) is the
/// TOPP-RA discretisation: the same K equal parts of task time, the task speed ṡ = v_i given at
/// the knots τ_i = i·Tp/K (0 < i < K; v_0 = v_K = 0, rest to rest) and s̈ constant on each part,
///   a_i = (v_{i+1}² − v_i²)/(2Δτ),   part duration δ_i = 2Δτ/(v_i + v_{i+1}),
/// so s is piecewise quadratic, C¹, monotone (ṡ between v_i and v_{i+1} ≥ 0) and
/// s(δ_0 + … + δ_{K−1}) = Tp by construction; s̈ may jump at every knot (bang-bang profiles are
/// represented exactly up to the knot grid) and s⃛ = 0.
/// time_law_function(f, law) is f(s(t)) with exact derivatives by the chain rule.

#include "refdyn/expression/symbolic_form.hpp"
#include "refdyn/expression/time_function.hpp"

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace refdyn {

struct TimeLawValue {
  double s = 0, ds = 0, dds = 0, ddds = 0;  ///< s(t), ṡ, s̈, s⃛
};

enum class TimeLawForm {
  segments,     ///< the real duration d_i of each part (cubic Hermite s)
  knot_speeds,  ///< the task speed v_i at the inner knots (piecewise quadratic s, TOPP-RA)
};

class TimeLaw {
 public:
  /// Throws Error for task_duration ≤ 0, no segments, or a segment ≤ 0 or not finite.
  TimeLaw(Number task_duration, std::vector<Number> segments);
  /// form segments: as above; form knot_speeds: `values` are v_1 … v_{K−1} (K − 1 ≥ 1 of them),
  /// each > 0 and finite (Error otherwise).
  TimeLaw(TimeLawForm form, Number task_duration, std::vector<Number> values);
  TimeLawForm form() const { return form_; }
  TimeLawValue eval(double t) const;
  double task_duration() const { return Tp_; }
  double end_time() const { return knots_.back(); }  ///< Σ d_i
  int segments() const { return static_cast<int>(knots_.size()) - 1; }  ///< K (both forms)
  const std::vector<double>& knots() const { return knots_; }  ///< t_0 = 0, t_1, …, t_K
  /// Knot slope m_i = ṡ(t_i) (i = 0..K); for the knot_speeds form v_i.
  double slope(int i) const { return m_[i]; }
  /// The law's numbers as written: task_duration and d_1 … d_K (segments) or v_1 … v_{K−1}
  /// (knot_speeds). Below, θ_0 = task_duration and θ_{1+j} = values()[j].
  const Number& task_duration_number() const { return Tp_; }
  const std::vector<Number>& values() const { return d_; }

  /// s, ṡ, s̈ at a fixed t and their exact derivatives in the law's numbers θ, by code (dual
  /// numbers through the same part formulas as eval): the part i holding t depends on its start
  /// knot t_{i−1} (which depends on every part before it: knot_derivatives) and directly on at most
  /// four θ (segments: Tp, d_{i−1}, d_i, d_{i+1}; knot_speeds: Tp, v_{i−1}, v_i). For any K the
  /// cost is constant. Outside [0, end] the law is constant (0 before, Tp after: ∂s/∂Tp = 1).
  struct Jet {
    TimeLawValue value;                          ///< eval(t)
    int knot = -1;                               ///< i − 1 (−1: t outside the law)
    std::array<int, 4> theta{-1, -1, -1, -1};    ///< the θ the part depends on directly (−1: none)
    std::array<std::array<double, 4>, 3> d{};    ///< d[k][l] = ∂(s, ṡ, s̈)_k/∂θ_{theta[l]}
    std::array<double, 3> dknot{};               ///< ∂(s, ṡ, s̈)_k/∂t_{i−1}
  };
  Jet jet(double t) const;
  /// ∂t_i/∂θ for i = 0 … K as dense rows over θ (K + 1 rows of 1 + values().size()), each the
  /// sum of the parts' durations' derivatives before it (t_0 = 0): O(K²) numbers, for tests; the
  /// sensitivities accumulate the same sums in the chosen parameters (duration_jet).
  std::vector<std::vector<double>> knot_derivatives() const;
  /// ∂(t_i − t_{i−1})/∂θ of part i = 1 … K: at most three θ (−1: none).
  struct DurationJet {
    std::array<int, 3> theta{-1, -1, -1};
    std::array<double, 3> d{};
  };
  DurationJet duration_jet(int i) const;
  /// s(t) as a text of the expression language in t: a chain of if(t < t_i, piece_i, …) with the
  /// durations (or knot speeds) and Tp written as their scenario texts (parameter names stay
  /// symbols); for knot_speeds the knot times t_i are written as sums of 2Δτ/(v_j + v_{j+1}).
  std::string symbolic_text() const;
  /// The text of end_time(): d1 + … + dK, or Σ 2Δτ/(v_i + v_{i+1}) (scenario texts kept).
  std::string end_text() const;
  bool has_texts() const;
  /// t_i (i = 0..K) as a text of the scenario's texts (d1 + d2, or sums of 2Δτ/(v_j + v_{j+1})).
  std::string knot_text(size_t i) const;

 private:

  TimeLawForm form_ = TimeLawForm::segments;
  Number Tp_;
  std::vector<Number> d_;  ///< segments: d_1 … d_K; knot_speeds: v_1 … v_{K−1}
  std::vector<double> knots_, m_;
};
using TimeLawPtr = std::shared_ptr<const TimeLaw>;

/// The symbols of the local form of s(t) (LocalTimeLawForm): t_c, s(t_c), ṡ(t_c), s̈(t_c).
inline constexpr std::array<const char*, 4> kTimeLawSymbols{"rd_tl_t", "rd_tl_s", "rd_tl_ds", "rd_tl_dds"};

/// While an object of this type lives (in this thread), symbolic() of a function on a time law
/// (time_law_function) writes s(t) not as the law's piecewise text but as its local form
///     rd_tl_s + rd_tl_ds·(t − rd_tl_t) + rd_tl_dds·(t − rd_tl_t)²/2,
/// in the four symbols kTimeLawSymbols, which the caller binds to t_c = t and to s, ṡ, s̈ of the
/// law at t (TimeLaw::eval): at t = t_c its value and its first two time derivatives are the
/// law's, exactly, so constraints of order ≤ 2 and their γ differentiated from it are exact; the
/// text has the same size for any K. The sensitivities (symbolic/sensitivity.hpp) evaluate the law
/// natively this way; `refdyn generate` writes the piecewise text (symbolic_text).
class LocalTimeLawForm {
 public:
  LocalTimeLawForm();
  ~LocalTimeLawForm();
  LocalTimeLawForm(const LocalTimeLawForm&) = delete;
  LocalTimeLawForm& operator=(const LocalTimeLawForm&) = delete;

 private:
  bool before_;
};

/// f(s(t)): f' ṡ, f'' ṡ² + f' s̈, f''' ṡ³ + 3 f'' ṡ s̈ + f' s⃛ (Faà di Bruno). Its symbolic form is
/// f's with every `t` replaced by the text of s(t).
TimeFunctionPtr time_law_function(TimeFunctionPtr inner, TimeLawPtr law);

/// `text` with every identifier `name` (a whole word, not part of another name or a call
/// like name(…) ) replaced by "(replacement)".
std::string replace_identifier(const std::string& text, const std::string& name, const std::string& replacement);
/// Whether `text` uses the identifier `name` as a variable (a whole word, not a call).
bool uses_identifier(const std::string& text, const std::string& name);

}  // namespace refdyn
