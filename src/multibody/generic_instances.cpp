// Explicit instantiations of the generic multibody core (refdyn/multibody/) for double and the
// one- and eight-direction dual numbers: every template compiles for the numeric scalars even
// where no caller uses it yet. (GiNaC::ex is instantiated by the code generator, src/symbolic/.)
#include "refdyn/multibody/dual.hpp"
#include "refdyn/multibody/generic_dynamics.hpp"

namespace refdyn::multibody {

#define REFDYN_MULTIBODY_INSTANTIATE(S)                                                                         \
  template Bodies<S> bodies_from_model<S, ExactLift<S>>(const Model&, const ExactLift<S>&);                    \
  template void transform_inertia<S>(const PoseT<S>&, const S&, Vec3T<S>&, Mat3T<S>&);                          \
  template void joint_transform<S>(const Body<S>&, const S&, Mat3T<S>&, Vec3T<S>&);                              \
  template void forward_poses<S>(const Bodies<S>&, const std::vector<S>&, Poses<S>&);                           \
  template void forward_motion<S>(const Bodies<S>&, const Poses<S>&, const S*, const S*, const Vec3T<S>&, bool,   \
                                  Motions<S>&);                                                                 \
  template PointKinematics<S> point_kinematics<S>(const Point<S>&, const Poses<S>&, const Motions<S>&);         \
  template Vec3T<S> point_jacobian_column<S>(const Bodies<S>&, const Poses<S>&, int, const Vec3T<S>&);          \
  template void newton_euler_backward<S>(const Bodies<S>&, const Poses<S>&, const Motions<S>&,                   \
                                         std::vector<Vec3T<S>>&, std::vector<Vec3T<S>>&, std::vector<S>&);       \
  template void inverse_dynamics<S>(const Bodies<S>&, const Poses<S>&, const Vec3&, const S*, const S*, bool,      \
                                    NewtonEulerWork<S>&, std::vector<S>&);                                       \
  template std::vector<S> inverse_dynamics<S>(const Bodies<S>&, const Poses<S>&, const Vec3&, const S*, const S*, \
                                              bool);                                                            \
  template std::vector<S> mass_matrix<S>(const Bodies<S>&, const Poses<S>&);                                   \
  template std::vector<S> crba<S>(const Bodies<S>&, const Poses<S>&);

REFDYN_MULTIBODY_INSTANTIATE(double)
REFDYN_MULTIBODY_INSTANTIATE(Dual<1>)
REFDYN_MULTIBODY_INSTANTIATE(Dual<8>)

#undef REFDYN_MULTIBODY_INSTANTIATE

}  // namespace refdyn::multibody
