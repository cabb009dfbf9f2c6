// inverse_dynamics_dual (dual_dynamics.hpp).
#include "refdyn/multibody/dual_dynamics.hpp"

#include "refdyn/multibody/body.hpp"
#include "refdyn/multibody/generic_dynamics.hpp"

#include <algorithm>

namespace refdyn {

namespace {
using D = JacobianScalar;
struct DualModelWork {
  std::uint64_t model_id = 0;  // the model `bodies` were converted from (ids are unique)
  multibody::Bodies<D> bodies;
  multibody::Poses<D> poses;
  multibody::NewtonEulerWork<D> ne;
  std::vector<D> q, tau;
};
}  // namespace

void inverse_dynamics_dual(const Model& model, const D* q, const D* qd, const D* qdd, bool with_gravity, D* tau) {
  thread_local DualModelWork w;
  if (w.model_id != model.id || w.bodies.size() != model.nv) {
    w.bodies = multibody::bodies_from_model<D>(model);
    w.model_id = model.id;
  }
  w.q.assign(q, q + model.nv);
  multibody::forward_poses(w.bodies, w.q, w.poses);
  multibody::inverse_dynamics(w.bodies, w.poses, model.gravity, qd, qdd, with_gravity, w.ne, w.tau);
  std::copy(w.tau.begin(), w.tau.end(), tau);
}

}  // namespace refdyn
