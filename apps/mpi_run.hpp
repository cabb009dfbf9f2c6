#pragma once
/// `refdyn track FILE -o DIR --mpi` under mpirun: every rank loads the scenario and plans (the
/// plan is deterministic, so every rank has the same one), runs the experiments i with
/// i % size == rank on its own threads and writes their track_<name>.csv (DIR on a file system
/// all ranks see); rank 0 gathers the runs' summaries and writes plan.csv, feasibility.json,
/// sweep.csv and summary.json — the same files as one process writes (tests/mpi_test.sh).
/// Built only when CMake finds MPI (Debian: libopenmpi-dev, openmpi-bin); otherwise every call
/// but mpi_available() throws an Error saying how to get it.

#include "refdyn/io/results.hpp"
#include "refdyn/io/variants.hpp"

#include <string>
#include <vector>

namespace refdyn::app {

/// refdyn was built with MPI.
bool mpi_available();

/// MPI_Init_thread (funneled: only the main thread calls MPI) … MPI_Finalize.
class MpiSession {
 public:
  MpiSession();
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }
  /// Collective: throws refdyn::Error on every rank when `error` is non-empty on any (the
  /// message of the lowest such rank), so that no rank waits for one that gave up.
  void agree(const std::string& error) const;
  /// Collective: every rank throws refdyn::Error(message), rank 0 having printed it first (as
  /// main prints an error, then no more): a rank that exits non-zero makes mpirun end the job, so
  /// rank 0 must not leave its line to after MPI_Finalize (it was lost now and then).
  [[noreturn]] void fail(const std::string& message) const;
  /// Collective: the summaries of every rank's finished runs reach rank 0's `results` (there
  /// RunRecord::done becomes true for all of them).
  void gather_runs(io::Results& results) const;
  /// Collective: the same for a family's variants (VariantSummary::done).
  void gather_variants(std::vector<io::VariantSummary>& summaries) const;
  /// Collective: rank 0's value on every rank.
  int broadcast(int value) const;
  /// Collective: every rank's bytes, concatenated in rank order, on rank 0 (empty elsewhere).
  std::vector<char> gather_bytes(const std::vector<char>& mine) const;

 private:
  int rank_ = 0, size_ = 1;
};

}  // namespace refdyn::app
