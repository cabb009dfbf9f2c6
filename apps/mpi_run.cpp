// MPI for `refdyn track --mpi` (apps/mpi_run.hpp). The runs' summaries travel as flat byte
// buffers: numbers as their bytes (bit-exact), strings with their length.
#include "mpi_run.hpp"

#include "commands.hpp"

#include "refdyn/common/error.hpp"

#include "refdyn/common/fields.hpp"

#include <cstdint>
#include <cstdio>
#include <functional>
#include <string>
#include <type_traits>
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
void MpiSession::fail(const std::string&) const { no_mpi(); }
void MpiSession::gather_runs(io::Results&) const { no_mpi(); }
void MpiSession::gather_variants(std::vector<io::VariantSummary>&) const { no_mpi(); }
std::vector<char> MpiSession::gather_bytes(const std::vector<char>&) const { no_mpi(); }
int MpiSession::broadcast(int) const { no_mpi(); }

#else

bool mpi_available() { return true; }

namespace {

template <class V>
struct is_vector : std::false_type {};
template <class E>
struct is_vector<std::vector<E>> : std::true_type {};

/// The MPI payload of described structs (common/fields.hpp): every stored field marked
/// sink::Wire, in the order listed: numbers as their bytes (bit-exact), strings and vectors with
/// their length, enums as int32, flags as int32.
class Writer {
 public:
  template <class T>
  void put(const T& x) {
    if constexpr (std::is_same_v<T, std::string>) {
      put(static_cast<std::uint64_t>(x.size()));
      bytes.insert(bytes.end(), x.begin(), x.end());
    } else if constexpr (std::is_enum_v<T> || std::is_same_v<T, bool>) {
      put(static_cast<std::int32_t>(x));
    } else if constexpr (is_described_v<T>) {
      for_each_field<T>([&](const auto& f) {
        if constexpr (std::decay_t<decltype(f)>::stored)
          if (f.in & sink::Wire) put(f.get(x));
      });
    } else if constexpr (is_vector<T>::value) {
      put(static_cast<std::uint64_t>(x.size()));
      for (const auto& e : x) put(e);
    } else {
      static_assert(std::is_arithmetic_v<T>);
      const auto* b = reinterpret_cast<const char*>(&x);
      bytes.insert(bytes.end(), b, b + sizeof(T));
    }
  }
  std::vector<char> bytes;
};

class Reader {
 public:
  Reader(const char* p, size_t n) : p_(p), end_(p + n) {}
  template <class T>
  void get(T& x) {
    if constexpr (std::is_same_v<T, std::string>) {
      const auto n = take<std::uint64_t>();
      need(n);
      x.assign(p_, p_ + n);
      p_ += n;
    } else if constexpr (std::is_enum_v<T>) {
      x = static_cast<T>(take<std::int32_t>());
    } else if constexpr (std::is_same_v<T, bool>) {
      x = take<std::int32_t>() != 0;
    } else if constexpr (is_described_v<T>) {
      for_each_field<T>([&](const auto& f) {
        if constexpr (std::decay_t<decltype(f)>::stored)
          if (f.in & sink::Wire) get(f.ref(x));
      });
    } else if constexpr (is_vector<T>::value) {
      const auto n = take<std::uint64_t>();
      need(n);  // at least a byte each: a bad count fails here, not in resize
      x.resize(n);
      for (auto& e : x) get(e);
    } else {
      x = take<T>();
    }
  }
  template <class T>
  T take() {
    static_assert(std::is_arithmetic_v<T>);
    need(sizeof(T));
    T x;
    std::memcpy(&x, p_, sizeof(T));
    p_ += sizeof(T);
    return x;
  }
  bool done() const { return p_ == end_; }

 private:
  void need(size_t n) const {
    if (static_cast<size_t>(end_ - p_) < n) throw Error("--mpi: a run summary from another rank is truncated (internal error)");
  }
  const char* p_;
  const char* end_;
};

/// Rank 0 receives the records (index, record) of the other ranks and marks them done.
template <class Record, class Done>
void gather_records(const MpiSession& mpi, std::vector<Record>& records, const Done& done, const char* what,
                    const std::function<void(size_t)>& mark_done) {
  Writer w;
  if (mpi.rank() != 0)
    for (size_t i = 0; i < records.size(); ++i) {
      if (!done(i)) continue;
      w.put(static_cast<std::uint64_t>(i));
      w.put(records[i]);
    }
  const std::vector<char> all = mpi.gather_bytes(w.bytes);
  if (mpi.rank() != 0) return;
  Reader in(all.data(), all.size());
  while (!in.done()) {
    const auto i = in.take<std::uint64_t>();
    if (i >= records.size()) throw Error(std::string("--mpi: a ") + what + " index from another rank is out of range (internal error)");
    in.get(records[i]);
    mark_done(i);
  }
}

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
  fail(msg);
}

void MpiSession::fail(const std::string& message) const {
  if (rank_ == 0 && error_output()) {
    std::string line = message;
    for (char& ch : line)
      if (ch == '\n') ch = ' ';
    std::fprintf(stderr, "refdyn: error: %s\n", line.c_str());
    std::fflush(stderr);
  }
  set_error_output(false);  // said once, by rank 0
  check(MPI_Barrier(MPI_COMM_WORLD), "MPI_Barrier");
  throw Error(message);
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
  std::vector<io::RunSummary> summaries(res.runs.size());
  for (size_t i = 0; i < res.runs.size(); ++i)
    if (rank_ != 0 && res.runs[i].done) summaries[i] = res.runs[i].summary;
  gather_records(*this, summaries, [&](size_t i) { return res.runs[i].done; }, "run", [&](size_t i) {
    res.runs[i].summary = std::move(summaries[i]);
    res.runs[i].done = true;
  });
}

void MpiSession::gather_variants(std::vector<io::VariantSummary>& summaries) const {
  gather_records(*this, summaries, [&](size_t i) { return summaries[i].done; }, "variant",
                 [&](size_t i) { summaries[i].done = true; });
}

#endif

}  // namespace refdyn::app
