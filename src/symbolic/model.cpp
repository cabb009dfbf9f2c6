// The bodies of a model as GiNaC expressions (numeric or parameter-valued geometry and inertia);
// their kinematics and joint-space inverse dynamics are the generic core's
// (refdyn/multibody/generic_dynamics.hpp) over GiNaC::ex. Nothing is expanded: GiNaC shares
// sub-expressions, and the C writer's common-subexpression elimination keeps them shared.
#include "internal.hpp"

#include "refdyn/multibody/detail/fold.hpp"

#include "refdyn/common/error.hpp"

#include <cln/float.h>

#include <cmath>
#include <limits>
#include <map>

namespace refdyn::symbolic_detail {

namespace {
using multibody::add;
using multibody::mul;
using multibody::scale;
using multibody::skew;
using Pose = multibody::PoseT<ex>;
Vec3s zero3() { return multibody::zero3<ex>(); }
Mat3s zero33() { return multibody::zero33<ex>(); }
Pose rot_x(const ex& a) { return multibody::rot_x(a); }
Pose rot_y(const ex& a) { return multibody::rot_y(a); }
Pose rot_z(const ex& a) { return multibody::rot_z(a); }
Vec3s vec(const Vec3& v) { return {number(v.x()), number(v.y()), number(v.z())}; }
}  // namespace

ex number(double v) {
  if (v == std::trunc(v) && std::fabs(v) < 9007199254740992.0) return GiNaC::numeric(static_cast<long>(v));
  // the double exactly, as the rational m·2^e: GiNaC's arithmetic on it is exact, so no result
  // depends on the order in which GiNaC combines numbers (an address-seeded hash order)
  int e = 0;
  const double f = std::frexp(v, &e);
  const long m = static_cast<long>(std::ldexp(f, 53));
  return GiNaC::numeric(m) * GiNaC::numeric(2).power(e - 53);
}

namespace {
ex constant_evalf(const ex& v) { return v.evalf(); }
ex constant_derivative(const ex&, unsigned) { return 0; }

/// True if e names no symbol (numbers, π, model constants, and operations on them).
bool constant_only(const ex& e) {
  if (is_a<GiNaC::symbol>(e)) return false;
  for (size_t i = 0; i < e.nops(); ++i)
    if (!constant_only(e.op(i))) return false;
  return true;
}

/// True if e still holds a call of the function with this serial (GiNaC left it unevaluated).
bool has_call(const ex& e, unsigned serial) {
  if (is_a<GiNaC::function>(e) && GiNaC::ex_to<GiNaC::function>(e).get_serial() == serial) return true;
  for (size_t i = 0; i < e.nops(); ++i)
    if (has_call(e.op(i), serial)) return true;
  return false;
}

double value_of(const ex& x) { return GiNaC::ex_to<GiNaC::numeric>(x.evalf()).to_double(); }

/// GiNaC's f(x), or the double f(x) as a model constant when x is a constant GiNaC leaves f of.
ex function_of(const ex& x, const ex& exact_result, unsigned serial, double (*f)(double)) {
  if (!constant_only(x) || !has_call(exact_result, serial)) return exact_result;
  return model_constant(f(value_of(x)));
}
}  // namespace

unsigned serial_constant() {
  static const unsigned serial = GiNaC::function::register_new(
      GiNaC::function_options("rd_const", 1).evalf_func(constant_evalf).derivative_func(constant_derivative));
  return serial;
}

ex model_constant(double v) {
  if (v == std::trunc(v) && std::fabs(v) < 9007199254740992.0) return number(v);
  const ex c = GiNaC::function(serial_constant(), number(std::fabs(v)));
  return v < 0 ? -c : c;
}

ex sin_of(const ex& x) {
  static const unsigned serial = GiNaC::ex_to<GiNaC::function>(GiNaC::sin(GiNaC::symbol("x"))).get_serial();
  return function_of(x, GiNaC::sin(x), serial, [](double v) { return std::sin(v); });
}

ex cos_of(const ex& x) {
  static const unsigned serial = GiNaC::ex_to<GiNaC::function>(GiNaC::cos(GiNaC::symbol("x"))).get_serial();
  return function_of(x, GiNaC::cos(x), serial, [](double v) { return std::cos(v); });
}

ex sqrt_of(const ex& x) {
  if (constant_only(x) && has_call(x, serial_constant())) return model_constant(std::sqrt(value_of(x)));
  return GiNaC::sqrt(x);
}

namespace {
struct Exact : GiNaC::map_function {
  ex operator()(const ex& e) override {
    if (is_a<GiNaC::numeric>(e)) {
      const GiNaC::numeric& x = GiNaC::ex_to<GiNaC::numeric>(e);
      if (x.is_real() && !x.is_rational()) return number(x.to_double());
      return e;
    }
    return e.map(*this);
  }
};
}  // namespace

ex exact(const ex& e) {
  Exact f;
  return f(e);
}

Vec3s clean(const Vec3& v) {
  const double tol = 4 * std::numeric_limits<double>::epsilon() * v.cwiseAbs().maxCoeff();
  Vec3 c = v;
  for (int k = 0; k < 3; ++k)
    if (std::fabs(c[k]) <= tol) c[k] = 0;
  return vec(c);
}

Mat3s rotation(const Mat3& R) {
  const double tol = 4 * std::numeric_limits<double>::epsilon();
  Mat3s S;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const double v = R(i, j);
      S[3 * i + j] = std::fabs(v) <= tol ? ex(0) : std::fabs(v - 1) <= tol ? ex(1) : std::fabs(v + 1) <= tol ? ex(-1) : model_constant(v);
    }
  return S;
}

ex CleanLift::scalar(double v) const { return number(v); }
Vec3s CleanLift::axis(const Vec3& v) const { return vec(v); }
Vec3s CleanLift::vector(const Vec3& v) const { return clean(v); }
Mat3s CleanLift::rotation(const Mat3& R) const { return symbolic_detail::rotation(R); }
Mat3s CleanLift::inertia(const Mat3& I) const {
  const double tol = 4 * std::numeric_limits<double>::epsilon() * I.cwiseAbs().maxCoeff();
  Mat3s S;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) S[3 * r + c] = std::fabs(I(r, c)) <= tol ? ex(0) : number(I(r, c));
  return S;
}


namespace {
using Fold = multibody::FoldAlgebra<ex>;

/// The numbers of the model section as expressions (`value`: a parameter stays a symbol).
struct Numbers {
  const QuantityValue& value;
  Vec3s v3(const ModelNumbers::Vec& n) const { return {value(n[0]), value(n[1]), value(n[2])}; }
  /// {xyz, rpy}, URDF convention R = Rz(yaw) Ry(pitch) Rx(roll)
  Pose pose(const ModelNumbers::Pose& n) const {
    Pose X;
    if (n.xyz) X.p = v3(*n.xyz);
    if (n.rpy) {
      const Vec3s r = v3(*n.rpy);
      X.R = (rot_z(r[2]) * rot_y(r[1]) * rot_x(r[0])).R;
    }
    return X;
  }
  ex number_or_zero(const std::optional<Quantity>& q) const { return q ? value(*q) : ex(0); }
  /// Mass, centre of mass and the inertia about it (9 elements, the diagonal, or 6: xx yy zz xy xz
  /// yz), as the inertia about the link's origin.
  Fold::Inertia inertia(const ModelNumbers::Link& n) const {
    ex m = 0;
    Vec3s com = zero3();
    Mat3s Ic = zero33();
    if (n.mass) m = value(*n.mass);
    if (n.com) com = v3(*n.com);
    const auto& I = n.inertia;
    if (I.size() == 9) {
      for (int k = 0; k < 9; ++k) Ic[k] = value(I[k]);
    } else if (I.size() == 3) {
      for (int r = 0; r < 3; ++r) Ic[4 * r] = value(I[r]);
    } else if (I.size() == 6) {
      ex x[6];
      for (int k = 0; k < 6; ++k) x[k] = value(I[k]);
      Ic = {x[0], x[3], x[4], x[3], x[1], x[5], x[4], x[5], x[2]};
    }
    return Fold::from_com(m, com, Ic);
  }
};

/// One link of the section: its joint's frames from the DH numbers or its origin, and its inertia;
/// `offset`: its joint offset.
multibody::FoldLink<ex> link_from_numbers(const ModelNumbers& spec, const ModelNumbers::Link& n, const Numbers& num,
                                          ex& offset) {
  multibody::FoldLink<ex> l;
  l.parent = n.parent;
  l.type = n.type;
  if (spec.dh) {
    const multibody::DHFrames<ex> f =
        multibody::dh_frames(n.type, num.number_or_zero(n.theta), num.number_or_zero(n.d), num.number_or_zero(n.a),
                             num.number_or_zero(n.alpha), spec.standard);
    l.placement = f.placement;
    l.link_offset = f.link_offset;
    offset = f.offset;
  } else {
    l.placement = num.pose(n.origin);
    l.link_offset = num.pose(n.link_offset);
    offset = n.offset ? num.value(*n.offset) : ex(0);
  }
  l.inertia = num.inertia(n);
  return l;
}

/// Points: in the link frame as written, expressed in the body frame (multibody::place_point).
void place_points(const Model& model, const ModelNumbers& spec, const Pose& base, const Numbers& num,
                  const multibody::Folded<ex>& f, SymbolicBodies& out) {
  std::map<std::string, int> link_index;
  for (int i = 0; i < static_cast<int>(spec.links.size()); ++i) link_index[spec.links[i].name] = i;
  out.points.resize(model.point_name.size());
  for (const ModelNumbers::Point& p : spec.points) {
    const int link = p.link == "world" ? multibody::kOnWorld
                     : p.link == "base" ? multibody::kOnBase
                                        : link_index.at(p.link);
    const multibody::FoldedPoint<ex> fp =
        multibody::place_point(f, link, base, p.position ? num.v3(*p.position) : zero3());
    out.points[model.point_index(p.name)] = {fp.body, fp.position};
  }
}
}  // namespace

SymbolicBodies bodies_from_numbers(const Model& model, const ModelNumbers& spec, const QuantityValue& value) {
  const Numbers num{value};
  std::vector<multibody::FoldLink<ex>> links;
  std::vector<ex> offsets(spec.links.size());
  for (size_t i = 0; i < spec.links.size(); ++i) links.push_back(link_from_numbers(spec, spec.links[i], num, offsets[i]));
  const Pose base = num.pose(spec.base);
  const multibody::Folded<ex> f = multibody::fold_links(links, base);
  if (f.size() != model.nq)
    throw Error("generate: the model section gives " + std::to_string(f.size()) + " bodies, the model has " +
                std::to_string(model.nq) + " (internal error)");
  SymbolicBodies out;
  for (int b = 0; b < f.size(); ++b) {
    const int i = f.link_of_body[b];
    SymbolicBody B;
    B.parent = f.parent[b];
    B.type = links[i].type;
    B.axis = vec(model.axis[b]);
    B.R = f.placement[b].R;
    B.p = f.placement[b].p;
    B.offset = offsets[i];
    B.m = f.inertia[b].m;
    B.h = f.inertia[b].h;
    B.I = f.inertia[b].I;
    // armature: as written (a parameter stays a symbol), else the compiled model's number
    const std::optional<Quantity>& a = spec.links[i].armature;
    B.armature = a ? num.value(*a) : number(model.armature[b]);
    out.bodies.push_back(B);
  }
  place_points(model, spec, base, num, f, out);
  return out;
}

SymbolicModel symbolic_model(const SymbolicBodies& bodies, const Vec3& gravity, const std::vector<ex>& q) {
  SymbolicModel s;
  s.bodies = bodies;
  s.gravity = gravity;
  s.q = q;
  multibody::forward_poses(s.bodies, q, s.poses);
  return s;
}

std::vector<ex> SymbolicModel::inverse_dynamics(const std::vector<ex>& qd, const std::vector<ex>& qdd,
                                                bool with_gravity) const {
  return multibody::inverse_dynamics(bodies, poses, gravity, qd.empty() ? nullptr : qd.data(),
                                     qdd.empty() ? nullptr : qdd.data(), with_gravity);
}

}  // namespace refdyn::symbolic_detail
