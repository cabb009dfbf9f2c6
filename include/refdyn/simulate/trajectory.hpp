#pragma once
/// Recorded motions: Trajectory (one entry per output sample), Plan (a solved reference
/// dynamics, with its RK4 stage values for the closed loops) and what a planner records.

#include "refdyn/simulate/integrators.hpp"

#include <Eigen/Core>
#include <initializer_list>
#include <limits>
#include <string>
#include <vector>

namespace refdyn {

/// The reference's RK4 stage values, recorded once (see the header comment).
struct ReferenceStages {
  double t0 = 0, h = 0;
  std::vector<double> breakpoints; ///< the grid's breakpoints (IntegratorOptions::breakpoints, Rk4Grid)
  long steps = 0;                  ///< complete steps recorded
  int n = 0;
  std::vector<double> data;        ///< per step, per stage (4), [q̂, q̂̇, q̂̈] (3n doubles)
  const double* stage(long step, int s) const { return data.data() + ((step * 4 + s) * 3 * n); }
  /// Per step, per stage, [ż, λ] (extra_size = nz + m doubles; plans of acceleration-level
  /// problems, else 0): with `data`, everything the sensitivities (symbolic/sensitivity.hpp) need
  /// of a stage, so that they do not evaluate the reference dynamics again.
  int extra_size = 0;
  std::vector<double> extra;
  const double* stage_extra(long step, int s) const { return extra.data() + ((step * 4 + s) * extra_size); }
};

/// One vector per output sample, the samples stored one after another in one buffer (a run of
/// 2001 samples and eight series is eight buffers, not 16,000 heap blocks: recording, copying and
/// freeing a trajectory cost a few allocations, and repeated runs do not churn the heap). Reads
/// like std::vector<Eigen::VectorXd>: s[k] is a map of sample k's vector (valid until the next
/// push_back), s.front(), s.back(), s.size(), range-for over the samples. Samples may differ in
/// size (a series is usually of one width).
class SampleSeries {
 public:
  using ConstSample = Eigen::Map<const Eigen::VectorXd>;
  using Sample = Eigen::Map<Eigen::VectorXd>;

  SampleSeries() = default;
  /// From separately stored vectors (tests, callers that built their samples one by one).
  SampleSeries(const std::vector<Eigen::VectorXd>& samples) { append(samples); }  // NOLINT: reads like one
  SampleSeries(std::initializer_list<Eigen::VectorXd> samples) { append(samples); }

  size_t size() const { return offset_.empty() ? 0 : offset_.size() - 1; }
  bool empty() const { return size() == 0; }
  /// Room for n samples; the values' room follows from the first sample's size.
  void reserve(size_t n) {
    offset_.reserve(n + 1);
    reserve_samples_ = n;
  }
  void clear() {
    offset_.clear();
    values_.clear();
  }
  /// Appends a copy of v (any Eigen vector expression; v may be a sample of this series).
  template <class Derived>
  void push_back(const Eigen::MatrixBase<Derived>& v) {
    const Eigen::Index w = v.size();
    if (offset_.empty()) {
      offset_.push_back(0);
      if (reserve_samples_ > 0) values_.reserve(reserve_samples_ * static_cast<size_t>(w));
    }
    const size_t at = values_.size();
    if (values_.capacity() < at + static_cast<size_t>(w)) {
      const Eigen::VectorXd copy = v;  // v may live in values_, which grows now
      values_.resize(at + static_cast<size_t>(w));
      Sample(values_.data() + at, w) = copy;
    } else {
      values_.resize(at + static_cast<size_t>(w));
      Sample(values_.data() + at, w) = v;
    }
    offset_.push_back(values_.size());
  }

  ConstSample operator[](size_t k) const { return {values_.data() + offset_[k], width(k)}; }
  Sample operator[](size_t k) { return {values_.data() + offset_[k], width(k)}; }
  ConstSample front() const { return (*this)[0]; }
  Sample front() { return (*this)[0]; }
  ConstSample back() const { return (*this)[size() - 1]; }
  Sample back() { return (*this)[size() - 1]; }
  Eigen::Index width(size_t k) const { return static_cast<Eigen::Index>(offset_[k + 1] - offset_[k]); }

  /// Iteration over the samples (maps, by value).
  template <class Series, class Map>
  class Iterator {
   public:
    Iterator(Series* s, size_t k) : s_(s), k_(k) {}
    Map operator*() const { return (*s_)[k_]; }
    Iterator& operator++() { return ++k_, *this; }
    bool operator!=(const Iterator& o) const { return k_ != o.k_; }
    bool operator==(const Iterator& o) const { return k_ == o.k_; }
   private:
    Series* s_;
    size_t k_;
  };
  using const_iterator = Iterator<const SampleSeries, ConstSample>;
  using iterator = Iterator<SampleSeries, Sample>;
  const_iterator begin() const { return {this, 0}; }
  const_iterator end() const { return {this, size()}; }
  iterator begin() { return {this, 0}; }
  iterator end() { return {this, size()}; }

 private:
  std::vector<double> values_;  ///< the samples, one after another
  std::vector<size_t> offset_;  ///< sample k is values_[offset_[k], offset_[k + 1]); empty: no samples
  size_t reserve_samples_ = 0;

  template <class Range>
  void append(const Range& samples) {
    reserve(size() + samples.size());
    for (const Eigen::VectorXd& v : samples) push_back(v);
  }
};

/// A recorded motion, one entry per output sample. What is recorded depends on the recorder:
/// a plan fills the reference-dynamics series (q̈, Φ, Φ̇, λ, Q_c, efforts), a closed loop the
/// tracking series (τ, q̂, q̂̇); series a recorder does not fill stay empty. Names say what the
/// columns of each vector series are; io/trajectory_io.hpp writes any Trajectory as CSV.
struct Trajectory {
  // ---- layout ----
  std::vector<std::string> joints;          ///< q, q̇, q̈, Q_c, efforts, τ, q̂: one per joint
  std::vector<std::string> state_names;     ///< the states after [q; q̇] in x (force elements, controller)
  std::vector<std::string> points;          ///< recorded points (3 columns each: x, y, z in the world)
  std::vector<std::string> constraint_rows; ///< Φ, Φ̇, λ: one per constraint row
  std::vector<char> material_row;           ///< per constraint row: material (1) or programmed (0)
  std::vector<std::string> target_signals;  ///< functions of t prescribed by constraints (record_as)
  std::vector<std::string> force_signals;   ///< quantities of force elements (a drive's ψ_dr, torque)

  // ---- samples ----
  std::vector<double> t;
  SampleSeries x;           ///< [q; q̇; states]
  SampleSeries qdd;         ///< q̈ (plans)
  SampleSeries point_positions;  ///< 3 × points
  SampleSeries targets, forces;  ///< target_signals, force_signals values
  SampleSeries phi, phid, lambda;  ///< constraint rows (plans)
  SampleSeries Qc;          ///< Q_c = M q̈ − F = −Aᵀλ, all rows (plans)
  /// What the actuators must deliver: actuator force elements (drives, efforts) plus the forces
  /// of the programmed constraints (plans). Feasibility checks this against effort limits.
  SampleSeries actuator_effort;
  /// Reaction forces of the material constraints (pins, rolling without slip): carried by the
  /// structure, not by the actuators (plans; empty when there are no material constraints).
  SampleSeries reaction_effort;
  SampleSeries tau, q_ref, qd_ref;  ///< applied τ and the reference (closed loops)

  size_t size() const { return t.size(); }
  int nq() const { return static_cast<int>(joints.size()); }
};

/// A planned motion: the reference dynamics integrated and recorded at every output sample.
struct Plan : Trajectory {
  IntegrationSummary summary;
  ReferenceStages stages;            ///< filled for RK4
};

/// What plan_motion records besides the state (model point indices, e.g. a scenario's outputs).
struct RecordOptions {
  std::vector<int> points;
  /// The plan stops at the first output sample (t >= residual_from) whose constraint residual
  /// max |Phi| exceeds this (or is not a number): that sample is not recorded, the plan ends at
  /// the one before with status ResidualExceeded. Infinity: no check (the library default).
  double residual_tolerance = std::numeric_limits<double>::infinity();
};

}  // namespace refdyn
