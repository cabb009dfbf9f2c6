#pragma once
// Orocos KDL as a benchmark peer, behind a plain interface (raw doubles in and out).
//
// Debian's KDL is built for baseline x86-64 (SSE2) while refdyn is compiled with
// -march=native. Eigen objects allocated under one alignment setting and freed under another
// crash, and inline Eigen functions compiled both ways would be merged by the linker, so the
// KDL side lives in its own shared library (refdyn_kdl_peer), compiled with the default flags
// and hidden visibility: nothing but this class crosses the boundary, and no Eigen or KDL type
// appears in this header.

#include "dh_tables.hpp"

#include <memory>

#if defined(__GNUC__)
#define REFDYN_KDL_PEER_API __attribute__((visibility("default")))
#else
#define REFDYN_KDL_PEER_API
#endif

namespace refdyn_bench {

class REFDYN_KDL_PEER_API KdlPeer {
 public:
  /// Builds a KDL::Chain from the standard-DH table: one segment per row with
  /// Joint::RotZ / Joint::TransZ, tip frame KDL::Frame::DH(a, α, d, θ) and
  /// KDL::RigidBodyInertia(m, com, I_com) (KDL takes the rotational inertia about the COM).
  explicit KdlPeer(const DHTable& table);
  ~KdlPeer();
  KdlPeer(const KdlPeer&) = delete;
  KdlPeer& operator=(const KdlPeer&) = delete;

  int dof() const;

  /// Stores `count` states (each argument: count × n doubles, state k at offset k·n).
  void load_states(const double* q, const double* qd, const double* qdd, int count);

  // The timed kernels, on stored state k; results stay inside (see the getters). Each returns
  // KDL's error code (0 on success).
  int mass_matrix(int k);                 ///< ChainDynParam::JntToMass
  int coriolis(int k);                    ///< ChainDynParam::JntToCoriolis
  int gravity(int k);                     ///< ChainDynParam::JntToGravity
  int inverse_dynamics(int k);            ///< ChainIdSolver_RNE::CartToJnt (no external wrenches)

  void get_mass_matrix(double* M_colmajor) const;  ///< n × n
  void get_coriolis(double* c) const;
  void get_gravity(double* g) const;
  void get_tau(double* tau) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace refdyn_bench
