// Symbolic kinematics and dynamics (GiNaC): the bodies of a model with numeric or
// parameter-valued geometry and inertia, their world poses, and the joint-space inverse dynamics
// by Newton–Euler in body frames. Nothing is expanded: GiNaC shares sub-expressions, and the C
// writer's common-subexpression elimination keeps them shared.
#include "internal.hpp"

#include "refdyn/common/error.hpp"

#include <cln/float.h>

#include <cmath>
#include <limits>
#include <map>

namespace refdyn::symbolic_detail {

namespace {

Vec3s add(const Vec3s& a, const Vec3s& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3s scale(const Vec3s& a, const ex& s) { return {a[0] * s, a[1] * s, a[2] * s}; }
Vec3s cross(const Vec3s& a, const Vec3s& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
ex dot(const Vec3s& a, const Vec3s& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3s mul(const Mat3s& R, const Vec3s& v) {
  return {R[0] * v[0] + R[1] * v[1] + R[2] * v[2], R[3] * v[0] + R[4] * v[1] + R[5] * v[2],
          R[6] * v[0] + R[7] * v[1] + R[8] * v[2]};
}
Mat3s mul(const Mat3s& A, const Mat3s& B) {
  Mat3s C;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
  return C;
}
Mat3s transpose(const Mat3s& A) {
  Mat3s T;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) T[3 * i + j] = A[3 * j + i];
  return T;
}
Mat3s identity3() { return {ex(1), ex(0), ex(0), ex(0), ex(1), ex(0), ex(0), ex(0), ex(1)}; }
Mat3s zero33() { return {ex(0), ex(0), ex(0), ex(0), ex(0), ex(0), ex(0), ex(0), ex(0)}; }
Mat3s skew(const Vec3s& a) { return {ex(0), -a[2], a[1], a[2], ex(0), -a[0], -a[1], a[0], ex(0)}; }
Mat3s plus(const Mat3s& A, const Mat3s& B) {
  Mat3s C;
  for (int k = 0; k < 9; ++k) C[k] = A[k] + B[k];
  return C;
}
Mat3s times(const Mat3s& A, const ex& s) {
  Mat3s C;
  for (int k = 0; k < 9; ++k) C[k] = A[k] * s;
  return C;
}
Vec3s vec(const Vec3& v) { return {number(v.x()), number(v.y()), number(v.z())}; }
Vec3s zero3() { return {ex(0), ex(0), ex(0)}; }

/// A symbolic pose: R (rotation), p (translation).
struct Pose {
  Mat3s R = identity3();
  Vec3s p = zero3();
  Pose operator*(const Pose& o) const { return {mul(R, o.R), add(mul(R, o.p), p)}; }
};
Pose rot_x(const ex& a) {
  const ex c = GiNaC::cos(a), s = GiNaC::sin(a);
  return {{ex(1), ex(0), ex(0), ex(0), c, -s, ex(0), s, c}, zero3()};
}
Pose rot_y(const ex& a) {
  const ex c = GiNaC::cos(a), s = GiNaC::sin(a);
  return {{c, ex(0), s, ex(0), ex(1), ex(0), -s, ex(0), c}, zero3()};
}
Pose rot_z(const ex& a) {
  const ex c = GiNaC::cos(a), s = GiNaC::sin(a);
  return {{c, -s, ex(0), s, c, ex(0), ex(0), ex(0), ex(1)}, zero3()};
}
Pose trans(const Vec3s& p) { return {identity3(), p}; }

/// Inertia (m, h = m c, I about the origin) given in B, expressed in A for the pose X of B in A:
/// h' = R h + m p, I' = R I Rᵀ − [p]×[Rh]× − [Rh]×[p]× − m [p]×² (parallel axes).
void transform_inertia(const Pose& X, const ex& m, Vec3s& h, Mat3s& I) {
  const Vec3s Rh = mul(X.R, h);
  const Mat3s P = skew(X.p), H = skew(Rh);
  I = plus(plus(mul(mul(X.R, I), transpose(X.R)), times(plus(mul(P, H), mul(H, P)), -1)), times(mul(P, P), -m));
  h = add(Rh, scale(X.p, m));
}

}  // namespace

ex number(double v) {
  if (v == std::trunc(v) && std::fabs(v) < 9007199254740992.0) return GiNaC::numeric(static_cast<long>(v));
  return GiNaC::numeric(cln::cl_float(v, cln::float_format_dfloat));
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
      S[3 * i + j] = std::fabs(v) <= tol ? ex(0) : std::fabs(v - 1) <= tol ? ex(1) : std::fabs(v + 1) <= tol ? ex(-1) : number(v);
    }
  return S;
}

SymbolicBodies bodies_from_model(const Model& model) {
  SymbolicBodies out;
  for (int i = 0; i < model.nq; ++i) {
    SymbolicBody b;
    b.parent = model.parent[i];
    b.type = model.joint_type[i];
    b.axis = model.axis[i];
    b.R = rotation(model.placement[i].R);
    b.p = clean(model.placement[i].p);
    b.offset = number(model.offset[i]);
    const Inertia& I = model.inertia[i];
    b.m = number(I.m);
    b.h = clean(I.h);
    const double tol = 4 * std::numeric_limits<double>::epsilon() * I.I.cwiseAbs().maxCoeff();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) b.I[3 * r + c] = std::fabs(I.I(r, c)) <= tol ? ex(0) : number(I.I(r, c));
    out.bodies.push_back(b);
  }
  for (size_t k = 0; k < model.point_name.size(); ++k)
    out.points.push_back({model.point_body[k], clean(model.point_position[k])});
  return out;
}

SymbolicBodies bodies_from_spec(const Model& model, const SpecValue& spec, const SpecNumber& value) {
  auto v3 = [&](const SpecValue& n) -> Vec3s { return {value(n[0]), value(n[1]), value(n[2])}; };
  auto pose = [&](const SpecValue& n) {  // {xyz, rpy}, URDF convention R = Rz(yaw) Ry(pitch) Rx(roll)
    Pose X;
    if (!n) return X;
    if (n["xyz"]) X.p = v3(n["xyz"]);
    if (n["rpy"]) {
      const Vec3s r = v3(n["rpy"]);
      X.R = (rot_z(r[2]) * rot_y(r[1]) * rot_x(r[0])).R;
    }
    return X;
  };
  struct Link {
    std::string name;
    int parent = -1;
    JointType type = JointType::Revolute;
    Pose placement, link_offset;
    ex offset = 0, m = 0;
    Vec3s com = zero3();
    Mat3s Ic = zero33();
  };
  auto inertia = [&](const SpecValue& n, Link& l) {
    if (n["mass"]) l.m = value(n["mass"]);
    if (n["com"]) l.com = v3(n["com"]);
    if (const SpecValue& I = n["inertia"]) {
      if (I.size() == 3 && I[0].is_list()) {
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) l.Ic[3 * r + c] = value(I[r][c]);
      } else if (I.size() == 3) {
        for (int r = 0; r < 3; ++r) l.Ic[4 * r] = value(I[r]);
      } else {
        ex x[6];
        for (int k = 0; k < 6; ++k) x[k] = value(I[k]);
        l.Ic = {x[0], x[3], x[4], x[3], x[1], x[5], x[4], x[5], x[2]};
      }
    }
  };
  auto joint_type = [](const SpecValue& n) {
    return n.text == "revolute" ? JointType::Revolute : n.text == "prismatic" ? JointType::Prismatic : JointType::Fixed;
  };
  std::vector<Link> links;
  if (const SpecValue& dh = spec["dh"]) {
    const bool standard = !dh["convention"] || dh["convention"].text == "standard";
    const SpecValue& js = dh["joints"];
    for (size_t i = 0; i < js.size(); ++i) {
      const SpecValue& j = js[i];
      Link l;
      l.name = j["link"] ? j["link"].text : j["name"].text;
      l.parent = static_cast<int>(i) - 1;
      l.type = joint_type(j["type"]);
      const ex theta = j["theta"] ? value(j["theta"]) : ex(0), d = j["d"] ? value(j["d"]) : ex(0);
      const ex a = j["a"] ? value(j["a"]) : ex(0), alpha = j["alpha"] ? value(j["alpha"]) : ex(0);
      // as from_dh: the joint variable enters through θ (revolute) or d (prismatic)
      Pose along_z = l.type == JointType::Prismatic ? rot_z(theta) : trans({ex(0), ex(0), d});
      if (l.type == JointType::Fixed) along_z = rot_z(theta) * trans({ex(0), ex(0), d});
      l.offset = l.type == JointType::Prismatic ? d : (l.type == JointType::Revolute ? theta : ex(0));
      const Pose x_part = trans({a, ex(0), ex(0)}) * rot_x(alpha);
      if (standard) {
        l.placement = along_z;
        l.link_offset = x_part;
      } else {
        l.placement = rot_x(alpha) * trans({a, ex(0), ex(0)}) * along_z;
      }
      inertia(j, l);
      links.push_back(l);
    }
  } else {
    const SpecValue& ls = spec["links"];
    std::map<std::string, int> index;
    for (size_t i = 0; i < ls.size(); ++i) {
      const SpecValue& n = ls[i];
      Link l;
      l.name = n["name"].text;
      if (n["parent"] && n["parent"].text != "base" && n["parent"].text != "world") l.parent = index.at(n["parent"].text);
      l.type = joint_type(n["type"]);
      l.placement = pose(n["origin"]);
      l.link_offset = pose(n["link_offset"]);
      if (n["offset"]) l.offset = value(n["offset"]);
      inertia(n, l);
      index[l.name] = static_cast<int>(links.size());
      links.push_back(l);
    }
  }
  const Pose base = pose(spec["base"]);

  // Fold as build_model: fixed joints into their parent body, link offsets into the body.
  SymbolicBodies out;
  const int nl = static_cast<int>(links.size());
  std::vector<int> body_of(nl, -1);
  std::vector<Pose> link_in_body(nl);
  std::map<std::string, int> link_index;
  for (int i = 0; i < nl; ++i) {
    const Link& l = links[i];
    link_index[l.name] = i;
    const int pb = l.parent < 0 ? -1 : body_of[l.parent];
    const Pose joint_in_pb = (l.parent < 0 ? base : link_in_body[l.parent]) * l.placement;
    Vec3s h = scale(l.com, l.m);
    Mat3s I = plus(l.Ic, times(mul(skew(l.com), skew(l.com)), -l.m));  // about the link origin
    if (l.type == JointType::Fixed) {
      body_of[i] = pb;
      link_in_body[i] = joint_in_pb * l.link_offset;
      if (pb >= 0) {
        transform_inertia(link_in_body[i], l.m, h, I);
        SymbolicBody& B = out.bodies[pb];
        B.m += l.m;
        B.h = add(B.h, h);
        B.I = plus(B.I, I);
      }
      continue;
    }
    const int b = static_cast<int>(out.bodies.size());
    body_of[i] = b;
    link_in_body[i] = l.link_offset;
    transform_inertia(l.link_offset, l.m, h, I);
    SymbolicBody B;
    B.parent = pb;
    B.type = l.type;
    B.axis = model.axis.at(b);
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
  // Points: in the link frame as written, expressed in the body frame.
  out.points.resize(model.point_name.size());
  if (const SpecValue& ps = spec["points"]) {
    for (const auto& kv : ps.entries) {
      const int k = model.point_index(kv.key);
      const std::string link = kv.value["link"].text;
      const Vec3s pos = kv.value["position"] ? v3(kv.value["position"]) : zero3();
      if (link == "world" || link == "base") {
        out.points[k] = {-1, pos};
      } else {
        const int li = link_index.at(link);
        const Pose& X = link_in_body[li];
        out.points[k] = {body_of[li], add(mul(X.R, pos), X.p)};
      }
    }
  }
  return out;
}

SymbolicModel symbolic_model(const SymbolicBodies& bodies, const Vec3& gravity, const std::vector<ex>& q) {
  SymbolicModel s;
  s.bodies = bodies;
  s.gravity = gravity;
  s.q = q;
  const int n = static_cast<int>(bodies.bodies.size());
  s.R.resize(n);
  s.r.resize(n);
  for (int i = 0; i < n; ++i) {
    const SymbolicBody& B = bodies.bodies[i];
    const ex x = q[i] + B.offset;
    Mat3s Rl = B.R;  // body orientation in the parent frame
    Vec3s pl = B.p;  // body origin in the parent frame
    const Vec3s a = vec(B.axis);
    if (B.type == JointType::Revolute) {
      const ex c = GiNaC::cos(x), sn = GiNaC::sin(x);
      // Rodrigues: c 1 + s [u]x + (1 − c) u uᵀ (exact zeros of u drop out)
      const Mat3s K = skew(a);
      Mat3s J;
      for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) J[3 * r + k] = (r == k ? c : ex(0)) + sn * K[3 * r + k] + (1 - c) * a[r] * a[k];
      Rl = mul(B.R, J);
    } else {
      pl = add(B.p, mul(B.R, scale(a, x)));
    }
    s.local_R.push_back(Rl);
    s.local_p.push_back(pl);
    if (B.parent < 0) {
      s.R[i] = Rl;
      s.r[i] = pl;
    } else {
      s.R[i] = mul(s.R[B.parent], Rl);
      s.r[i] = add(s.r[B.parent], mul(s.R[B.parent], pl));
    }
  }
  return s;
}

std::vector<ex> SymbolicModel::inverse_dynamics(const std::vector<ex>& qd, const std::vector<ex>& qdd,
                                                bool with_gravity) const {
  // Newton–Euler with every body quantity in the body's own frame: the joint axis is a number
  // there, and only one joint rotation separates a body from its parent, which keeps the
  // formulas short (a prismatic joint's M_ii is the sliding mass itself). With the inertia as
  // (m, h = m c, I about the origin O): F = m a_O + ω̇×h + ω×(ω×h), N_O = I ω̇ + ω×Iω + h×a_O.
  const int n = static_cast<int>(bodies.bodies.size());
  auto at = [](const std::vector<ex>& v, int i) { return v.empty() ? ex(0) : v[i]; };
  std::vector<Vec3s> w(n), wd(n), a(n), f(n), nn(n);
  std::vector<Mat3s> E(n);
  const Vec3s a_world = with_gravity ? scale(vec(gravity), -1) : zero3();  // base acceleration −g
  for (int i = 0; i < n; ++i) {
    const SymbolicBody& B = bodies.bodies[i];
    const int par = B.parent;
    E[i] = transpose(local_R[i]);  // parent → body
    const Vec3s& pl = local_p[i];
    const Vec3s w_p = par < 0 ? zero3() : w[par];
    const Vec3s wd_p = par < 0 ? zero3() : wd[par];
    const Vec3s a_p = par < 0 ? a_world : a[par];
    const Vec3s ax = vec(B.axis);
    const Vec3s w_in = mul(E[i], w_p);  // parent's angular velocity in body axes
    a[i] = mul(E[i], add(add(a_p, cross(wd_p, pl)), cross(w_p, cross(w_p, pl))));
    if (B.type == JointType::Revolute) {
      w[i] = add(w_in, scale(ax, at(qd, i)));
      wd[i] = add(add(mul(E[i], wd_p), scale(ax, at(qdd, i))), cross(w_in, scale(ax, at(qd, i))));
    } else {
      w[i] = w_in;
      wd[i] = mul(E[i], wd_p);
      a[i] = add(add(a[i], scale(cross(w_in, ax), 2 * at(qd, i))), scale(ax, at(qdd, i)));
    }
    f[i] = add(add(scale(a[i], B.m), cross(wd[i], B.h)), cross(w[i], cross(w[i], B.h)));
    nn[i] = add(add(mul(B.I, wd[i]), cross(w[i], mul(B.I, w[i]))), cross(B.h, a[i]));
  }
  std::vector<ex> tau(n);
  for (int i = n; i-- > 0;) {
    const SymbolicBody& B = bodies.bodies[i];
    const Vec3s ax = vec(B.axis);
    tau[i] = B.type == JointType::Revolute ? dot(ax, nn[i]) : dot(ax, f[i]);
    if (B.parent >= 0) {
      const Vec3s fp = mul(local_R[i], f[i]);
      f[B.parent] = add(f[B.parent], fp);
      nn[B.parent] = add(add(nn[B.parent], mul(local_R[i], nn[i])), cross(local_p[i], fp));
    }
  }
  return tau;
}

}  // namespace refdyn::symbolic_detail
