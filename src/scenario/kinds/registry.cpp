// The three registries, filled once from kinds.def, and their documentation.
#include "kinds.hpp"

#include <sstream>

namespace refdyn {

namespace {
struct Registries {
  Registry<ConstraintKind> constraints{"constraint kind"};
  Registry<ForceKind> forces{"force element type"};
  Registry<ControllerKind> controllers{"controller type"};
};

const Registries& registries() {
  static const Registries r = [] {
    Registries reg;
#define REFDYN_CONSTRAINT_KIND(n) reg.constraints.add(kinds::constraint_##n());
#define REFDYN_FORCE_KIND(n) reg.forces.add(kinds::force_##n());
#define REFDYN_CONTROLLER_KIND(n) reg.controllers.add(kinds::controller_##n());
#include "kinds.def"
#undef REFDYN_CONSTRAINT_KIND
#undef REFDYN_FORCE_KIND
#undef REFDYN_CONTROLLER_KIND
    return reg;
  }();
  return r;
}
}  // namespace

const Registry<ConstraintKind>& constraint_kinds() { return registries().constraints; }
const Registry<ForceKind>& force_kinds() { return registries().forces; }
const Registry<ControllerKind>& controller_kinds() { return registries().controllers; }

namespace {
std::vector<std::string> with(std::vector<std::string> common, const std::vector<KeyDoc>& keys) {
  for (const auto& k : keys) common.push_back(k.name);
  return common;
}

void key_table(std::ostringstream& os, const std::vector<KeyDoc>& keys) {
  for (const auto& k : keys) {
    os << "  - `" << k.name << "` (" << k.type;
    if (k.required)
      os << ", required";
    else if (!k.default_text.empty())
      os << ", default " << k.default_text;
    else
      os << ", optional";
    os << "): " << k.doc << "\n";
  }
}
}  // namespace

std::vector<std::string> allowed_keys(const ConstraintKind& k) { return with({"name", "origin", "kind"}, k.keys); }
std::vector<std::string> allowed_keys(const ForceKind& k) { return with({"type", "name"}, k.keys); }
std::vector<std::string> allowed_keys(const ControllerKind& k) { return with({"type"}, k.keys); }

std::string registry_markdown() {
  std::ostringstream os;
  os << "### Constraint kinds (`constraints:` entries: `name`, `origin: material|programmed`, `kind`)\n\n";
  for (const auto& k : constraint_kinds().entries()) {
    os << "- `kind: " << k.name << "` (default origin: " << to_string(k.default_origin) << ") — " << k.doc << "\n";
    key_table(os, k.keys);
  }
  os << "\n### Force elements (`forces:` and `plant_forces:` entries: `type`, optional `name`)\n\n";
  for (const auto& k : force_kinds().entries()) {
    os << "- `type: " << k.name << "` — " << k.doc << "\n";
    key_table(os, k.keys);
  }
  os << "\n### Controllers (`controller:`: `type`)\n\n";
  for (const auto& k : controller_kinds().entries()) {
    os << "- `type: " << k.name << "` — " << k.doc << "\n";
    key_table(os, k.keys);
  }
  return os.str();
}

}  // namespace refdyn
