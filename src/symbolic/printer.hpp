#pragma once
// Private to the generator's writers (emit_c.cpp: C99; emit.cpp: LaTeX and JSON; tape.cpp: the
// canonical graph all three print from): number formatting.
#include "../expression/internal.hpp"
#include "refdyn/common/error.hpp"

#include <ginac/ginac.h>

#include <cstdio>
#include <string>

namespace refdyn::symbolic_detail {

using GiNaC::ex;
using GiNaC::is_a;

/// v with `digits` significant digits (%g).
inline std::string double_text(double v, int digits) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

}  // namespace refdyn::symbolic_detail
