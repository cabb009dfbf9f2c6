#include "dh_models.hpp"

namespace refdyn_bench {

refdyn::ModelDescription description_from_table(const DHTable& t) {
  std::vector<refdyn::DHRow> rows;
  for (const auto& l : t.links) {
    refdyn::DHRow r;
    r.type = l.prismatic ? refdyn::JointType::Prismatic : refdyn::JointType::Revolute;
    r.theta = l.theta;
    r.d = l.d;
    r.a = l.a;
    r.alpha = l.alpha;
    r.inertia.mass = l.mass;
    r.inertia.com = refdyn::Vec3(l.com[0], l.com[1], l.com[2]);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) r.inertia.I_com(i, j) = l.I_com[3 * i + j];
    rows.push_back(r);
  }
  refdyn::ModelDescription d = refdyn::from_dh(rows, refdyn::DHConvention::Standard, t.name);
  for (size_t i = 0; i < t.links.size(); ++i) d.links[i].armature = t.links[i].armature;
  d.gravity = refdyn::Vec3(t.gravity[0], t.gravity[1], t.gravity[2]);
  return d;
}

}  // namespace refdyn_bench
