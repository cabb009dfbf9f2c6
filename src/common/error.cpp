#include "refdyn/common/error.hpp"

namespace refdyn {

std::string expected_got(std::string_view what, std::string_view expected, std::string_view got,
                         std::string_view hint) {
  std::string s(what);
  s += ": expected ";
  s += expected;
  s += ", got ";
  s += got;
  if (!hint.empty()) {
    s += " (hint: ";
    s += hint;
    s += ")";
  }
  return s;
}

void check_size(std::string_view what, Eigen::Index expected, Eigen::Index got,
                std::string_view hint) {
  if (expected != got)
    throw Error(expected_got(what, "size " + std::to_string(expected), "size " + std::to_string(got),
                             hint.empty() ? "the model's dimension is given by Model::nq" : hint));
}

}  // namespace refdyn
