#pragma once
// The refdyn side of the shared DH tables (dh_tables.hpp, which the KDL peer reads too, so that
// header stays free of refdyn): a table as a refdyn model description.
#include "dh_tables.hpp"
#include "refdyn/multibody/model.hpp"

namespace refdyn_bench {

/// The table as a model description: standard DH rows with the table's inertias, its name and
/// its gravity (no points; callers add theirs before build_model).
refdyn::ModelDescription description_from_table(const DHTable& t);

}  // namespace refdyn_bench
