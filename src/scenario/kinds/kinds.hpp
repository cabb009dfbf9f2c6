#pragma once
// Declarations of the registered kinds (generated from kinds.def).
#include "refdyn/scenario/registry.hpp"

namespace refdyn::kinds {
#define REFDYN_CONSTRAINT_KIND(n) ConstraintKind constraint_##n();
#define REFDYN_FORCE_KIND(n) ForceKind force_##n();
#define REFDYN_CONTROLLER_KIND(n) ControllerKind controller_##n();
#include "kinds.def"
#undef REFDYN_CONSTRAINT_KIND
#undef REFDYN_FORCE_KIND
#undef REFDYN_CONTROLLER_KIND
}  // namespace refdyn::kinds
