// Compiled WITHOUT -march=native (see kdl_peer.hpp): Debian's KDL is an SSE2 build.
#include "kdl_peer.hpp"

#include <kdl/chain.hpp>
#include <kdl/chaindynparam.hpp>
#include <kdl/chainidsolver_recursive_newton_euler.hpp>
#include <kdl/frames.hpp>
#include <kdl/jntarray.hpp>
#include <kdl/jntspaceinertiamatrix.hpp>
#include <kdl/rigidbodyinertia.hpp>
#include <kdl/rotationalinertia.hpp>
#include <kdl/segment.hpp>

#include <vector>

namespace refdyn_bench {

namespace {
KDL::Chain make_chain(const DHTable& t) {
  KDL::Chain chain;
  for (const DHLink& l : t.links) {
    const auto& I = l.I_com;  // row-major
    const KDL::RotationalInertia Ic(I[0], I[4], I[8], I[1], I[2], I[5]);
    const KDL::RigidBodyInertia rbi(l.mass, KDL::Vector(l.com[0], l.com[1], l.com[2]), Ic);
    const KDL::Joint joint(l.prismatic ? KDL::Joint::TransZ : KDL::Joint::RotZ);
    chain.addSegment(KDL::Segment(joint, KDL::Frame::DH(l.a, l.alpha, l.d, l.theta), rbi));
  }
  return chain;
}
}  // namespace

struct KdlPeer::Impl {
  explicit Impl(const DHTable& t)
      : chain(make_chain(t)),
        grav(t.gravity[0], t.gravity[1], t.gravity[2]),
        dyn(chain, grav),
        rne(chain, grav),
        n(static_cast<int>(chain.getNrOfJoints())),
        M(n),
        c(n),
        g(n),
        tau(n),
        fext(chain.getNrOfSegments(), KDL::Wrench::Zero()) {}
  KDL::Chain chain;
  KDL::Vector grav;
  KDL::ChainDynParam dyn;
  KDL::ChainIdSolver_RNE rne;
  int n;
  std::vector<KDL::JntArray> q, qd, qdd;
  KDL::JntSpaceInertiaMatrix M;
  KDL::JntArray c, g, tau;
  KDL::Wrenches fext;
};

KdlPeer::KdlPeer(const DHTable& table) : impl_(std::make_unique<Impl>(table)) {}
KdlPeer::~KdlPeer() = default;

int KdlPeer::dof() const { return impl_->n; }

void KdlPeer::load_states(const double* q, const double* qd, const double* qdd, int count) {
  Impl& s = *impl_;
  const int n = s.n;
  s.q.assign(count, KDL::JntArray(n));
  s.qd.assign(count, KDL::JntArray(n));
  s.qdd.assign(count, KDL::JntArray(n));
  for (int k = 0; k < count; ++k)
    for (int i = 0; i < n; ++i) {
      s.q[k](i) = q[k * n + i];
      s.qd[k](i) = qd[k * n + i];
      s.qdd[k](i) = qdd[k * n + i];
    }
}

int KdlPeer::mass_matrix(int k) { return impl_->dyn.JntToMass(impl_->q[k], impl_->M); }
int KdlPeer::coriolis(int k) { return impl_->dyn.JntToCoriolis(impl_->q[k], impl_->qd[k], impl_->c); }
int KdlPeer::gravity(int k) { return impl_->dyn.JntToGravity(impl_->q[k], impl_->g); }
int KdlPeer::inverse_dynamics(int k) {
  return impl_->rne.CartToJnt(impl_->q[k], impl_->qd[k], impl_->qdd[k], impl_->fext, impl_->tau);
}

void KdlPeer::get_mass_matrix(double* M) const {
  const int n = impl_->n;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) M[j * n + i] = impl_->M(i, j);
}
void KdlPeer::get_coriolis(double* c) const {
  for (int i = 0; i < impl_->n; ++i) c[i] = impl_->c(i);
}
void KdlPeer::get_gravity(double* g) const {
  for (int i = 0; i < impl_->n; ++i) g[i] = impl_->g(i);
}
void KdlPeer::get_tau(double* tau) const {
  for (int i = 0; i < impl_->n; ++i) tau[i] = impl_->tau(i);
}

}  // namespace refdyn_bench
