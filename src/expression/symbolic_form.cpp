// symbolic_number (symbolic_form.hpp): texts of numbers for the symbolic forms
// that constraints, force elements and functions of time give the code generator.
#include "refdyn/expression/symbolic_form.hpp"

#include <cstdio>

namespace refdyn {

std::string symbolic_number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  std::string s = buf;
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";  // keep it a decimal (not inf/nan)
  return v < 0 ? "(" + s + ")" : s;
}

std::string symbolic_number(const Number& n) { return n.text.empty() ? symbolic_number(n.value) : "(" + n.text + ")"; }

}  // namespace refdyn
