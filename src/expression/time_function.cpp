#include "refdyn/expression/time_function.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"

#include <cmath>
#include <numbers>

namespace refdyn {

namespace {
constexpr double kTwoPi = 2.0 * std::numbers::pi;

void need_finite(double x, const char* what, const char* fn) {
  if (!std::isfinite(x)) throw Error(std::string(fn) + ": " + what + " must be a finite number, got " + fmt(x));
}

class Constant final : public TimeFunction {
 public:
  explicit Constant(double c) : c_(c) {}
  TimeValue eval(double) const override { return {c_, 0, 0, 0}; }
  std::string describe() const override { return fmt(c_); }
  std::optional<SymbolicForm> symbolic() const override { return symbolic_rows({symbolic_number(c_)}); }
 private:
  double c_;
};

class Polynomial final : public TimeFunction {
 public:
  explicit Polynomial(std::vector<double> c) : c_(std::move(c)) {}
  TimeValue eval(double t) const override {
    TimeValue v;  // Horner for f, f', f'', f'''
    for (size_t k = c_.size(); k-- > 0;) {
      v.dddf = v.dddf * t + 3 * v.ddf;
      v.ddf = v.ddf * t + 2 * v.df;
      v.df = v.df * t + v.f;
      v.f = v.f * t + c_[k];
    }
    return v;
  }
  std::string describe() const override {
    std::string s;
    for (size_t k = 0; k < c_.size(); ++k) s += (k ? " + " : "") + fmt(c_[k]) + (k ? "*t^" + std::to_string(k) : "");
    return s.empty() ? "0" : s;
  }
  std::optional<SymbolicForm> symbolic() const override {
    std::string s;
    for (size_t k = 0; k < c_.size(); ++k)
      s += (k ? " + " : "") + symbolic_number(c_[k]) + (k ? "*t^" + std::to_string(k) : "");
    return symbolic_rows({s.empty() ? "0" : s});
  }
 private:
  std::vector<double> c_;
};

class Sinusoid final : public TimeFunction {
 public:
  Sinusoid(double a, double w, double p, double o) : a_(a), w_(w), p_(p), o_(o) {}
  TimeValue eval(double t) const override {
    const double s = std::sin(w_ * t + p_), c = std::cos(w_ * t + p_);
    return {o_ + a_ * s, a_ * w_ * c, -a_ * w_ * w_ * s, -a_ * w_ * w_ * w_ * c};
  }
  std::string describe() const override {
    return fmt(o_) + " + " + fmt(a_) + "*sin(" + fmt(w_) + "*t + " + fmt(p_) + ")";
  }
  std::optional<SymbolicForm> symbolic() const override {
    return symbolic_rows({symbolic_number(o_) + " + " + symbolic_number(a_) + "*sin(" + symbolic_number(w_) + "*t + " +
                         symbolic_number(p_) + ")"});
  }
 private:
  double a_, w_, p_, o_;
};

class RaisedCosine final : public TimeFunction {
 public:
  RaisedCosine(Number f0, Number df, Number T) : f0_(std::move(f0)), df_(std::move(df)), w_(kTwoPi / T), T_(std::move(T)) {}
  TimeValue eval(double t) const override {
    const double c = std::cos(w_ * t), s = std::sin(w_ * t);
    return {f0_ + df_ * (1 - c) / 2, df_ * w_ * s / 2, df_ * w_ * w_ * c / 2, -df_ * w_ * w_ * w_ * s / 2};
  }
  std::string describe() const override {
    return fmt(f0_) + " + " + fmt(df_) + "*(1 - cos(2*pi*t/" + fmt(T_) + "))/2";
  }
  std::optional<SymbolicForm> symbolic() const override {
    SymbolicForm f = symbolic_rows({symbolic_number(f0_) + " + " + symbolic_number(df_) + "*(1 - cos(2*pi*t/" +
                                    symbolic_number(T_) + "))/2"});
    f.scenario_texts = any_text(f0_, df_, T_);
    return f;
  }
 private:
  Number f0_, df_;
  double w_;
  Number T_;
};

class Cycloidal final : public TimeFunction {
 public:
  Cycloidal(Number rise, Number dur, Number f0, Number t0)
      : r_(std::move(rise)), d_(std::move(dur)), f0_(std::move(f0)), t0_(std::move(t0)) {}
  TimeValue eval(double t) const override {
    const double tau = (t - t0_) / d_;
    // f''' jumps at both ends (0 outside, 4π² rise/duration³ cos 2πτ inside): at τ = 0 and
    // τ = 1 themselves it is the constant branch's 0 (f, f', f'' are continuous there).
    if (tau <= 0) return {f0_, 0, 0, 0};
    if (tau >= 1) return {f0_ + r_, 0, 0, 0};
    const double s = std::sin(kTwoPi * tau), c = std::cos(kTwoPi * tau);
    return {f0_ + r_ * (tau - s / kTwoPi), r_ / d_ * (1 - c), r_ / (d_ * d_) * kTwoPi * s,
            r_ / (d_ * d_ * d_) * kTwoPi * kTwoPi * c};
  }
  std::string describe() const override {
    return "cycloidal rise " + fmt(r_) + " over " + fmt(d_) + " s from t = " + fmt(t0_);
  }
  std::optional<SymbolicForm> symbolic() const override {
    // τ clamped to [0, 1]: constant before and after (clamp's derivatives are those of the
    // inside branch at the ends, where the rise has zero velocity and acceleration anyway)
    const std::string tau = "clamp((t - " + symbolic_number(t0_) + ")/" + symbolic_number(d_) + ", 0, 1)";
    SymbolicForm f = symbolic_rows({symbolic_number(f0_) + " + " + symbolic_number(r_) + "*(" + tau + " - sin(2*pi*" +
                                    tau + ")/(2*pi))"});
    f.scenario_texts = any_text(r_, d_, f0_, t0_);
    return f;
  }
 private:
  Number r_, d_, f0_, t0_;  // with the scenario's texts, for the symbolic form
};
}  // namespace

TimeFunctionPtr constant(double c) {
  need_finite(c, "value", "constant");
  return std::make_shared<Constant>(c);
}
TimeFunctionPtr polynomial(std::vector<double> c) {
  for (double x : c) need_finite(x, "coefficient", "polynomial");
  return std::make_shared<Polynomial>(std::move(c));
}
TimeFunctionPtr sinusoid(double a, double w, double p, double o) {
  for (double x : {a, w, p, o}) need_finite(x, "parameter", "sinusoid");
  return std::make_shared<Sinusoid>(a, w, p, o);
}
TimeFunctionPtr raised_cosine(Number f0, Number df, Number T) {
  for (double x : {f0, df, T}) need_finite(x, "parameter", "raised_cosine");
  if (!(T > 0)) throw Error(expected_got("raised_cosine period", "> 0", fmt(T)));
  return std::make_shared<RaisedCosine>(std::move(f0), std::move(df), std::move(T));
}
TimeFunctionPtr cycloidal(Number rise, Number dur, Number f0, Number t0) {
  for (double x : {rise, dur, f0, t0}) need_finite(x, "parameter", "cycloidal");
  if (!(dur > 0)) throw Error(expected_got("cycloidal duration", "> 0", fmt(dur)));
  return std::make_shared<Cycloidal>(std::move(rise), std::move(dur), std::move(f0), std::move(t0));
}

}  // namespace refdyn
