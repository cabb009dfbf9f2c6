#pragma once
// Private to src/io/: readers of whole scenario sections that need nothing but the SpecReader,
// kept beside scenario.cpp (which reads the file and the other sections).
#include "refdyn/scenario/registry.hpp"  // SpecReader; the section specs (scenario/spec.hpp)

namespace refdyn::io::detail {

/// variants: (a sweep or a grid of parameters).
VariantsSpec read_variants(const SpecReader& c, const SpecValue& va);
/// optimize: (refdyn optimize, docs/optimize.md): the structure; names, bounds and expressions
/// are checked by the optimize layer (check_optimize).
OptimizeSpec read_optimize(const SpecReader& c, const SpecValue& op, const SourceLocation& at);

}  // namespace refdyn::io::detail
