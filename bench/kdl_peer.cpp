// Compiled WITHOUT -march=native (see kdl_peer.hpp): Debian's KDL is an SSE2 build.
#include "kdl_peer.hpp"

#include <kdl/chain.hpp>
#include <kdl/chaindynparam.hpp>
#include <kdl/chainfdsolver_recursive_newton_euler.hpp>
#include <kdl/chainfksolvervel_recursive.hpp>
#include <kdl/chainhdsolver_vereshchagin.hpp>
#include <kdl/chainidsolver_recursive_newton_euler.hpp>
#include <kdl/chainjnttojacdotsolver.hpp>
#include <kdl/chainjnttojacsolver.hpp>
#include <kdl/frames.hpp>
#include <kdl/framevel.hpp>
#include <kdl/jacobian.hpp>
#include <kdl/jntarray.hpp>
#include <kdl/jntarrayvel.hpp>
#include <kdl/jntspaceinertiamatrix.hpp>
#include <kdl/rigidbodyinertia.hpp>
#include <kdl/rotationalinertia.hpp>
#include <kdl/segment.hpp>
#include <kdl/tree.hpp>
#include <kdl/treeidsolver_recursive_newton_euler.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include <Eigen/Cholesky>

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace refdyn_bench {

namespace {
KDL::Chain make_chain(const DHTable& t) {
  KDL::Chain chain;
  for (const DHLink& l : t.links) {
    const auto& I = l.I_com;  // row-major
    const KDL::RotationalInertia Ic(I[0], I[4], I[8], I[1], I[2], I[5]);
    const KDL::RigidBodyInertia rbi(l.mass, KDL::Vector(l.com[0], l.com[1], l.com[2]), Ic);
    // KDL's joint inertia is refdyn's armature: JntToMass adds it to H(k,k), the RNE solver
    // inertia·q̈ to τ, Vereshchagin's solver to D.
    const KDL::Joint joint(l.prismatic ? KDL::Joint::TransZ : KDL::Joint::RotZ, 1.0, 0.0, l.armature);
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
        fd(chain, grav),
        n(static_cast<int>(chain.getNrOfJoints())),
        M(n),
        c(n),
        g(n),
        tau(n),
        fext(chain.getNrOfSegments(), KDL::Wrench::Zero()),
        qdd_out(n),
        llt_n(n) {}
  KDL::Chain chain;
  KDL::Vector grav;
  KDL::ChainDynParam dyn;
  KDL::ChainIdSolver_RNE rne;
  KDL::ChainFdSolver_RNE fd;  // keeps a reference to `chain`
  int n;
  std::vector<KDL::JntArray> q, qd, qdd;
  KDL::JntSpaceInertiaMatrix M;
  KDL::JntArray c, g, tau;
  KDL::Wrenches fext;
  // forward dynamics
  std::vector<KDL::JntArray> torques;
  KDL::JntArray qdd_out;
  int m = 0;
  std::vector<Eigen::MatrixXd> A;
  std::vector<Eigen::VectorXd> rhs;
  Eigen::LLT<Eigen::MatrixXd> llt_n, llt_m;
  Eigen::MatrixXd Y, S;
  Eigen::VectorXd u, lambda;
  // Vereshchagin (after setup_vereshchagin). The solver keeps a reference to `chain`.
  std::unique_ptr<KDL::ChainHdSolver_Vereshchagin> hd;
  int nc = 0;
  std::vector<KDL::Jacobian> alfa;
  std::vector<KDL::JntArray> beta, ff;
  KDL::JntArray hd_qdd, hd_tau_c;
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

void KdlPeer::load_torques(const double* tau, int count) {
  Impl& s = *impl_;
  s.torques.assign(count, KDL::JntArray(s.n));
  for (int k = 0; k < count; ++k)
    for (int i = 0; i < s.n; ++i) s.torques[k](i) = tau[k * s.n + i];
}

int KdlPeer::forward_dynamics(int k) {
  Impl& s = *impl_;
  return s.fd.CartToJnt(s.q[k], s.qd[k], s.torques[k], s.fext, s.qdd_out);
}

void KdlPeer::set_constraints(const double* A, const double* rhs, int m, int count) {
  Impl& s = *impl_;
  s.m = m;
  s.A.assign(count, Eigen::MatrixXd(m, s.n));
  s.rhs.assign(count, Eigen::VectorXd(m));
  for (int k = 0; k < count; ++k) {
    s.A[k] = Eigen::Map<const Eigen::MatrixXd>(A + static_cast<size_t>(k) * m * s.n, m, s.n);
    s.rhs[k] = Eigen::Map<const Eigen::VectorXd>(rhs + static_cast<size_t>(k) * m, m);
  }
  s.llt_m = Eigen::LLT<Eigen::MatrixXd>(m);
  s.Y.resize(s.n, m);
  s.S.resize(m, m);
  s.u.resize(s.n);
  s.lambda.resize(m);
}

int KdlPeer::constrained_forward_dynamics(int k) {
  Impl& s = *impl_;
  if (int e = s.dyn.JntToMass(s.q[k], s.M); e < 0) return e;
  if (int e = s.dyn.JntToCoriolis(s.q[k], s.qd[k], s.c); e < 0) return e;
  if (int e = s.dyn.JntToGravity(s.q[k], s.g); e < 0) return e;
  // u = M⁻¹(τ − c − g), Y = M⁻¹Aᵀ, S = A Y, λ = S⁻¹(A u − rhs), q̈ = u − Y λ.
  s.llt_n.compute(s.M.data);
  if (s.llt_n.info() != Eigen::Success) return -100;
  s.u = -s.c.data - s.g.data;  // no applied forces (as on the refdyn side)
  s.llt_n.solveInPlace(s.u);
  const Eigen::MatrixXd& A = s.A[k];
  s.Y = A.transpose();
  s.llt_n.solveInPlace(s.Y);
  s.S.noalias() = A * s.Y;
  s.llt_m.compute(s.S);
  if (s.llt_m.info() != Eigen::Success) return -101;
  s.lambda.noalias() = A * s.u;
  s.lambda -= s.rhs[k];
  s.llt_m.solveInPlace(s.lambda);
  s.qdd_out.data = s.u;
  s.qdd_out.data.noalias() -= s.Y * s.lambda;
  return 0;
}

void KdlPeer::get_qdd(double* qdd) const {
  for (int i = 0; i < impl_->n; ++i) qdd[i] = impl_->qdd_out(i);
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

// ---- Vereshchagin ----

void KdlPeer::setup_vereshchagin(const double* root_acc, int nc) {
  Impl& s = *impl_;
  const KDL::Twist acc(KDL::Vector(root_acc[0], root_acc[1], root_acc[2]),
                       KDL::Vector(root_acc[3], root_acc[4], root_acc[5]));
  s.hd = std::make_unique<KDL::ChainHdSolver_Vereshchagin>(s.chain, acc, static_cast<unsigned>(nc));
  s.nc = nc;
  s.hd_qdd = KDL::JntArray(s.n);
  s.hd_tau_c = KDL::JntArray(s.n);
}

void KdlPeer::load_vereshchagin_inputs(const double* alfa, const double* beta, const double* ff_torques,
                                       int count) {
  Impl& s = *impl_;
  const int n = s.n, nc = s.nc;
  s.alfa.assign(count, KDL::Jacobian(nc));
  s.beta.assign(count, KDL::JntArray(nc));
  s.ff.assign(count, KDL::JntArray(n));
  for (int k = 0; k < count; ++k) {
    for (int c = 0; c < nc; ++c) {
      for (int r = 0; r < 6; ++r) s.alfa[k](r, c) = alfa[(k * nc + c) * 6 + r];
      s.beta[k](c) = beta[k * nc + c];
    }
    for (int i = 0; i < n; ++i) s.ff[k](i) = ff_torques[k * n + i];
  }
}

int KdlPeer::vereshchagin(int k) {
  Impl& s = *impl_;
  return s.hd->CartToJnt(s.q[k], s.qd[k], s.hd_qdd, s.alfa[k], s.beta[k], s.fext, s.ff[k], s.hd_tau_c);
}

void KdlPeer::get_vereshchagin_qdd(double* qdd) const {
  for (int i = 0; i < impl_->n; ++i) qdd[i] = impl_->hd_qdd(i);
}
void KdlPeer::get_vereshchagin_constraint_torques(double* tau_c) const {
  for (int i = 0; i < impl_->n; ++i) tau_c[i] = impl_->hd_tau_c(i);
}
void KdlPeer::get_vereshchagin_nu(double* nu) const {
  Eigen::VectorXd v(impl_->nc);
  impl_->hd->getContraintForceMagnitude(v);
  for (int c = 0; c < impl_->nc; ++c) nu[c] = v(c);
}
void KdlPeer::get_vereshchagin_tip_acceleration(double* acc6) const {
  std::vector<KDL::Twist> xdd(impl_->chain.getNrOfSegments() + 1);
  impl_->hd->getTransformedLinkAcceleration(xdd);
  const KDL::Twist& a = xdd.back();
  for (int i = 0; i < 3; ++i) {
    acc6[i] = a.vel(i);
    acc6[3 + i] = a.rot(i);
  }
}

int KdlPeer::tip_kinematics(int k, const double* qdd, double* pos3, double* twist6, double* acc6) {
  Impl& s = *impl_;
  const int n = s.n;
  KDL::JntArrayVel qv(s.q[k], s.qd[k]);
  KDL::FrameVel fv;
  KDL::ChainFkSolverVel_recursive fk(s.chain);
  if (int e = fk.JntToCart(qv, fv); e < 0) return e;
  KDL::Jacobian J(n);
  KDL::ChainJntToJacSolver jac(s.chain);
  if (int e = jac.JntToJac(s.q[k], J); e < 0) return e;
  KDL::ChainJntToJacDotSolver jacdot(s.chain);  // hybrid representation (the default)
  KDL::Twist jdqd;
  if (int e = jacdot.JntToJacDot(qv, jdqd); e < 0) return e;
  const KDL::Twist t = fv.GetTwist();
  for (int i = 0; i < 3; ++i) {
    pos3[i] = fv.GetFrame().p(i);
    twist6[i] = t.vel(i);
    twist6[3 + i] = t.rot(i);
  }
  for (int r = 0; r < 6; ++r) {
    double a = r < 3 ? jdqd.vel(r) : jdqd.rot(r - 3);
    for (int j = 0; j < n; ++j) a += J(r, j) * qdd[j];
    acc6[r] = a;
  }
  return 0;
}

// ---- a URDF through kdl_parser ----

struct KdlUrdfPeer::Impl {
  KDL::Tree tree;
  std::unique_ptr<KDL::TreeIdSolver_RNE> id;
  std::vector<std::string> names;
  KDL::JntArray q, qd, qdd, tau;
};

KdlUrdfPeer::KdlUrdfPeer(const std::string& urdf_path, const double* gravity) : impl_(std::make_unique<Impl>()) {
  if (!kdl_parser::treeFromFile(urdf_path, impl_->tree))
    throw std::runtime_error("kdl_parser could not read '" + urdf_path + "'");
  const unsigned n = impl_->tree.getNrOfJoints();
  impl_->names.assign(n, "");
  for (const auto& [segment_name, element] : impl_->tree.getSegments()) {
    const KDL::Joint& j = GetTreeElementSegment(element).getJoint();
    if (j.getType() != KDL::Joint::None) impl_->names.at(GetTreeElementQNr(element)) = j.getName();
  }
  impl_->id = std::make_unique<KDL::TreeIdSolver_RNE>(impl_->tree, KDL::Vector(gravity[0], gravity[1], gravity[2]));
  for (auto* a : {&impl_->q, &impl_->qd, &impl_->qdd, &impl_->tau}) a->resize(n);
}

KdlUrdfPeer::~KdlUrdfPeer() = default;

int KdlUrdfPeer::dof() const { return static_cast<int>(impl_->names.size()); }

std::string KdlUrdfPeer::joint_name(int i) const { return impl_->names.at(i); }

int KdlUrdfPeer::inverse_dynamics(const double* q, const double* qd, const double* qdd, double* tau) {
  const int n = dof();
  for (int i = 0; i < n; ++i) {
    impl_->q(i) = q[i];
    impl_->qd(i) = qd[i];
    impl_->qdd(i) = qdd[i];
  }
  const int rc = impl_->id->CartToJnt(impl_->q, impl_->qd, impl_->qdd, KDL::WrenchMap(), impl_->tau);
  for (int i = 0; i < n; ++i) tau[i] = impl_->tau(i);
  return rc;
}

}  // namespace refdyn_bench
