// MPI for `refdyn track --mpi` (apps/mpi_run.hpp). The runs' summaries travel as flat byte
// buffers: numbers as their bytes (bit-exact), strings with their length.
#include "mpi_run.hpp"

#include "refdyn/common/error.hpp"

#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#ifdef REFDYN_WITH_MPI
#include <mpi.h>
#endif

namespace refdyn::app {

#ifndef REFDYN_WITH_MPI

bool mpi_available() { return false; }
namespace {
[[noreturn]] void no_mpi() {
  throw Error("--mpi: this refdyn was built without MPI (install libopenmpi-dev and openmpi-bin, e.g. with "
              "scripts/install-deps.sh, then rebuild; or run without --mpi and use --jobs for the cores of one machine)");
}
}  // namespace
MpiSession::MpiSession() { no_mpi(); }
MpiSession::~MpiSession() = default;
void MpiSession::agree(const std::string&) const { no_mpi(); }
void MpiSession::gather_runs(io::Results&) const { no_mpi(); }
void MpiSession::gather_variants(std::vector<io::VariantSummary>&) const { no_mpi(); }
std::vector<char> MpiSession::gather_bytes(const std::vector<char>&) const { no_mpi(); }
int MpiSession::broadcast(int) const { no_mpi(); }

#else

bool mpi_available() { return true; }

namespace {

class Writer {
 public:
  template <class T>
  void put(const T& x) {
    const auto* b = reinterpret_cast<const char*>(&x);
    bytes.insert(bytes.end(), b, b + sizeof(T));
  }
  void put(const std::string& s) {
    put(static_cast<std::uint64_t>(s.size()));
    bytes.insert(bytes.end(), s.begin(), s.end());
  }
  std::vector<char> bytes;
};

class Reader {
 public:
  Reader(const char* p, size_t n) : p_(p), end_(p + n) {}
  template <class T>
  T get() {
    need(sizeof(T));
    T x;
    std::memcpy(&x, p_, sizeof(T));
    p_ += sizeof(T);
    return x;
  }
  std::string get_string() {
    const auto n = get<std::uint64_t>();
    need(n);
    std::string s(p_, p_ + n);
    p_ += n;
    return s;
  }
  bool done() const { return p_ == end_; }

 private:
  void need(size_t n) const {
    if (static_cast<size_t>(end_ - p_) < n) throw Error("--mpi: a run summary from another rank is truncated (internal error)");
  }
  const char* p_;
  const char* end_;
};

void check(int rc, const char* what) {
  if (rc != MPI_SUCCESS) throw Error(std::string("--mpi: ") + what + " failed (MPI error " + std::to_string(rc) + ")");
}

}  // namespace

MpiSession::MpiSession() {
  int initialized = 0;
  MPI_Initialized(&initialized);
  if (initialized) throw Error("--mpi: MPI is already initialized in this process");
  int provided = 0;
  check(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

MpiSession::~MpiSession() { MPI_Finalize(); }

void MpiSession::agree(const std::string& error) const {
  // The lowest rank with an error sends its message to all.
  int mine = error.empty() ? size_ : rank_, first = size_;
  check(MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD), "MPI_Allreduce");
  if (first == size_) return;
  int n = rank_ == first ? static_cast<int>(error.size()) : 0;
  check(MPI_Bcast(&n, 1, MPI_INT, first, MPI_COMM_WORLD), "MPI_Bcast");
  std::string msg(static_cast<size_t>(n), ' ');
  if (rank_ == first) msg = error;
  check(MPI_Bcast(msg.data(), n, MPI_CHAR, first, MPI_COMM_WORLD), "MPI_Bcast");
  throw Error(msg);
}

int MpiSession::broadcast(int value) const {
  check(MPI_Bcast(&value, 1, MPI_INT, 0, MPI_COMM_WORLD), "MPI_Bcast");
  return value;
}

std::vector<char> MpiSession::gather_bytes(const std::vector<char>& mine) const {
  int n = static_cast<int>(mine.size());
  std::vector<int> counts(rank_ == 0 ? size_ : 0), offsets(rank_ == 0 ? size_ : 0);
  check(MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD), "MPI_Gather");
  std::vector<char> all;
  if (rank_ == 0) {
    long total = 0;
    for (int r = 0; r < size_; ++r) offsets[r] = static_cast<int>(total), total += counts[r];
    if (total > std::numeric_limits<int>::max()) throw Error("--mpi: more than 2 GB of summaries to gather");
    all.resize(static_cast<size_t>(total));
  }
  check(MPI_Gatherv(mine.data(), n, MPI_CHAR, all.data(), counts.data(), offsets.data(), MPI_CHAR, 0, MPI_COMM_WORLD),
        "MPI_Gatherv");
  return all;
}

void MpiSession::gather_runs(io::Results& res) const {
  Writer w;
  if (rank_ != 0)
    for (size_t i = 0; i < res.runs.size(); ++i) {
      const io::RunRecord& r = res.runs[i];
      if (!r.done) continue;
      const io::RunSummary& s = r.summary;
      w.put(static_cast<std::uint64_t>(i));
      w.put(static_cast<std::int32_t>(s.status));
      w.put(s.message);
      w.put(s.t_end), w.put(s.steps), w.put(s.saturated_samples);
      w.put(s.final_max_abs_error), w.put(s.peak_abs_tau), w.put(s.wall_time);
      w.put(static_cast<std::uint64_t>(s.joints.size()));
      for (const auto& j : s.joints) w.put(j.e0), w.put(j.settle_time), w.put(j.late_error), w.put(j.peak_tau);
    }
  const std::vector<char> all = gather_bytes(w.bytes);
  if (rank_ != 0) return;
  Reader in(all.data(), all.size());
  while (!in.done()) {
    const auto i = in.get<std::uint64_t>();
    if (i >= res.runs.size()) throw Error("--mpi: a run index from another rank is out of range (internal error)");
    io::RunRecord& r = res.runs[i];
    io::RunSummary& s = r.summary;
    s.status = static_cast<IntegrationStatus>(in.get<std::int32_t>());
    s.message = in.get_string();
    s.t_end = in.get<double>(), s.steps = in.get<long>(), s.saturated_samples = in.get<long>();
    s.final_max_abs_error = in.get<double>(), s.peak_abs_tau = in.get<double>(), s.wall_time = in.get<double>();
    s.joints.resize(in.get<std::uint64_t>());
    for (auto& j : s.joints)
      j.e0 = in.get<double>(), j.settle_time = in.get<double>(), j.late_error = in.get<double>(), j.peak_tau = in.get<double>();
    r.done = true;
  }
}

void MpiSession::gather_variants(std::vector<io::VariantSummary>& summaries) const {
  Writer w;
  auto put_vector = [&w](const std::vector<double>& v) {
    w.put(static_cast<std::uint64_t>(v.size()));
    for (double x : v) w.put(x);
  };
  if (rank_ != 0)
    for (size_t i = 0; i < summaries.size(); ++i) {
      const io::VariantSummary& s = summaries[i];
      if (!s.done) continue;
      w.put(static_cast<std::uint64_t>(i));
      w.put(s.error);
      w.put(static_cast<std::int32_t>(s.status));
      w.put(s.message);
      w.put(s.t_end), w.put(s.max_constraint_residual), w.put(static_cast<std::int32_t>(s.feasible)), w.put(s.violations);
      put_vector(s.peak_speed);
      put_vector(s.peak_effort);
      w.put(s.runs), w.put(s.runs_completed), w.put(s.worst_final_error), w.put(s.worst_peak_tau), w.put(s.wall_time);
    }
  const std::vector<char> all = gather_bytes(w.bytes);
  if (rank_ != 0) return;
  Reader in(all.data(), all.size());
  auto get_vector = [&in] {
    std::vector<double> v(in.get<std::uint64_t>());
    for (double& x : v) x = in.get<double>();
    return v;
  };
  while (!in.done()) {
    const auto i = in.get<std::uint64_t>();
    if (i >= summaries.size()) throw Error("--mpi: a variant index from another rank is out of range (internal error)");
    io::VariantSummary& s = summaries[i];
    s.error = in.get_string();
    s.status = static_cast<IntegrationStatus>(in.get<std::int32_t>());
    s.message = in.get_string();
    s.t_end = in.get<double>(), s.max_constraint_residual = in.get<double>();
    s.feasible = in.get<std::int32_t>() != 0, s.violations = in.get<long>();
    s.peak_speed = get_vector();
    s.peak_effort = get_vector();
    s.runs = in.get<long>(), s.runs_completed = in.get<long>();
    s.worst_final_error = in.get<double>(), s.worst_peak_tau = in.get<double>(), s.wall_time = in.get<double>();
    s.done = true;
  }
}

#endif

}  // namespace refdyn::app
