// The bodies of a model as GiNaC expressions (numeric or parameter-valued geometry and inertia);
// their kinematics and joint-space inverse dynamics are the generic core's
// (refdyn/multibody/generic_dynamics.hpp) over GiNaC::ex. Nothing is expanded: GiNaC shares
// sub-expressions, and the C writer's common-subexpression elimination keeps them shared.
#include "internal.hpp"

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
Pose trans(const Vec3s& p) { return multibody::translation(p); }
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

SymbolicBodies bodies_from_model(const Model& model) {
  SymbolicBodies out;
  for (int i = 0; i < model.nq; ++i) {
    SymbolicBody b;
    b.parent = model.parent[i];
    b.type = model.joint_type[i];
    b.axis = vec(model.axis[i]);
    b.R = rotation(model.placement[i].R);
    b.p = clean(model.placement[i].p);
    b.offset = number(model.offset[i]);
    const Inertia& I = model.inertia[i];
    b.m = number(I.m);
    b.h = clean(I.h);
    const double tol = 4 * std::numeric_limits<double>::epsilon() * I.I.cwiseAbs().maxCoeff();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) b.I[3 * r + c] = std::fabs(I.I(r, c)) <= tol ? ex(0) : number(I.I(r, c));
    b.armature = number(model.armature[i]);
    out.bodies.push_back(b);
  }
  for (size_t k = 0; k < model.point_name.size(); ++k)
    out.points.push_back({model.point_body[k], clean(model.point_position[k])});
  return out;
}

namespace {
/// A link of the model section as expressions, before the fixed joints are folded.
struct Link {
  std::string name;
  int parent = -1;
  JointType type = JointType::Revolute;
  Pose placement, link_offset;
  ex offset = 0, m = 0;
  Vec3s com = zero3();
  Mat3s Ic = zero33();
};

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
  /// Mass, centre of mass and the inertia about it (9 elements, the diagonal, or 6: xx yy zz xy xz yz).
  void inertia(const ModelNumbers::Link& n, Link& l) const {
    if (n.mass) l.m = value(*n.mass);
    if (n.com) l.com = v3(*n.com);
    const auto& I = n.inertia;
    if (I.size() == 9) {
      for (int k = 0; k < 9; ++k) l.Ic[k] = value(I[k]);
    } else if (I.size() == 3) {
      for (int r = 0; r < 3; ++r) l.Ic[4 * r] = value(I[r]);
    } else if (I.size() == 6) {
      ex x[6];
      for (int k = 0; k < 6; ++k) x[k] = value(I[k]);
      l.Ic = {x[0], x[3], x[4], x[3], x[1], x[5], x[4], x[5], x[2]};
    }
  }
};

/// One link of the section: its joint's placement from the DH numbers (as from_dh) or its origin,
/// and its inertia.
Link link_from_numbers(const ModelNumbers& spec, const ModelNumbers::Link& n, const Numbers& num) {
  Link l;
  l.name = n.name;
  l.parent = n.parent;
  l.type = n.type;
  if (spec.dh) {
    const ex theta = num.number_or_zero(n.theta), d = num.number_or_zero(n.d);
    const ex a = num.number_or_zero(n.a), alpha = num.number_or_zero(n.alpha);
    // as from_dh: the joint variable enters through θ (revolute) or d (prismatic)
    Pose along_z = l.type == JointType::Prismatic ? rot_z(theta) : trans({ex(0), ex(0), d});
    if (l.type == JointType::Fixed) along_z = rot_z(theta) * trans({ex(0), ex(0), d});
    l.offset = l.type == JointType::Prismatic ? d : (l.type == JointType::Revolute ? theta : ex(0));
    const Pose x_part = trans({a, ex(0), ex(0)}) * rot_x(alpha);
    if (spec.standard) {
      l.placement = along_z;
      l.link_offset = x_part;
    } else {
      l.placement = rot_x(alpha) * trans({a, ex(0), ex(0)}) * along_z;
    }
  } else {
    l.placement = num.pose(n.origin);
    l.link_offset = num.pose(n.link_offset);
    if (n.offset) l.offset = num.value(*n.offset);
  }
  num.inertia(n, l);
  return l;
}

/// The bodies of the folded links, and where each link went.
struct Folded {
  SymbolicBodies out;
  std::vector<int> body_of;             ///< the body of each link (−1: the world)
  std::vector<Pose> link_in_body;       ///< each link's frame in its body's
  std::map<std::string, int> link_index;
};

/// Folds as build_model: fixed joints into their parent body, link offsets into the body.
Folded fold_links(const Model& model, const std::vector<Link>& links, const Pose& base) {
  Folded f;
  SymbolicBodies& out = f.out;
  const int nl = static_cast<int>(links.size());
  std::vector<int>& body_of = f.body_of;
  std::vector<Pose>& link_in_body = f.link_in_body;
  body_of.assign(nl, -1);
  link_in_body.resize(nl);
  for (int i = 0; i < nl; ++i) {
    const Link& l = links[i];
    f.link_index[l.name] = i;
    const int pb = l.parent < 0 ? -1 : body_of[l.parent];
    const Pose joint_in_pb = (l.parent < 0 ? base : link_in_body[l.parent]) * l.placement;
    Vec3s h = scale(l.com, l.m);
    Mat3s I = multibody::add(l.Ic, scale(mul(skew(l.com), skew(l.com)), ex(-l.m)));  // about the link origin
    if (l.type == JointType::Fixed) {
      body_of[i] = pb;
      link_in_body[i] = joint_in_pb * l.link_offset;
      if (pb >= 0) {
        multibody::transform_inertia(link_in_body[i], l.m, h, I);
        SymbolicBody& B = out.bodies[pb];
        B.m += l.m;
        B.h = add(B.h, h);
        B.I = multibody::add(B.I, I);
      }
      continue;
    }
    const int b = static_cast<int>(out.bodies.size());
    body_of[i] = b;
    link_in_body[i] = l.link_offset;
    multibody::transform_inertia(l.link_offset, l.m, h, I);
    SymbolicBody B;
    B.parent = pb;
    B.type = l.type;
    B.axis = vec(model.axis.at(b));
    B.R = joint_in_pb.R;
    B.p = joint_in_pb.p;
    B.offset = l.offset;
    B.m = l.m;
    B.h = h;
    B.I = I;
    out.bodies.push_back(B);
  }
  if (static_cast<int>(out.bodies.size()) != model.nq)
    throw Error("generate: the model section gives " + std::to_string(out.bodies.size()) + " bodies, the model has " +
                std::to_string(model.nq) + " (internal error)");
  return f;
}

/// Armature: as written (a parameter stays a symbol), else the compiled model's number.
void set_armature(const Model& model, const ModelNumbers& spec, const std::vector<Link>& links, const Numbers& num,
                  Folded& f) {
  for (int i = 0; i < static_cast<int>(links.size()); ++i)
    if (links[i].type != JointType::Fixed) {
      const std::optional<Quantity>& a = spec.links[i].armature;
      f.out.bodies[f.body_of[i]].armature = a ? num.value(*a) : number(model.armature[f.body_of[i]]);
    }
}

/// Points: in the link frame as written, expressed in the body frame.
void place_points(const Model& model, const ModelNumbers& spec, const Pose& base, const Numbers& num, Folded& f) {
  f.out.points.resize(model.point_name.size());
  for (const ModelNumbers::Point& p : spec.points) {
    const int k = model.point_index(p.name);
    const Vec3s pos = p.position ? num.v3(*p.position) : zero3();
    if (p.link == "world") {
      f.out.points[k] = {-1, pos};
    } else if (p.link == "base") {  // fixed in the world at the base pose (as build_model)
      f.out.points[k] = {-1, add(mul(base.R, pos), base.p)};
    } else {
      const int li = f.link_index.at(p.link);
      const Pose& X = f.link_in_body[li];
      f.out.points[k] = {f.body_of[li], add(mul(X.R, pos), X.p)};
    }
  }
}
}  // namespace

SymbolicBodies bodies_from_numbers(const Model& model, const ModelNumbers& spec, const QuantityValue& value) {
  const Numbers num{value};
  std::vector<Link> links;
  for (const ModelNumbers::Link& n : spec.links) links.push_back(link_from_numbers(spec, n, num));
  const Pose base = num.pose(spec.base);
  Folded f = fold_links(model, links, base);
  set_armature(model, spec, links, num, f);
  place_points(model, spec, base, num, f);
  return std::move(f.out);
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
