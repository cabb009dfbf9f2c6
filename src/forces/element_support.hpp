#pragma once
// Private to src/forces/ (not installed): what the elements' files share.
#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/forces/force_elements.hpp"

#include <string>

/// For an element whose law<S> is defined in its .cpp (a class in a header, as FlexibleDrive):
/// instantiates it for the scalars ForceLaw uses (double, JacobianScalar, Dual<1>, Formula).
#define REFDYN_INSTANTIATE_FORCE_LAW(Element)                                                                      \
  template void Element::law<double>(const double&, const double*, const double*, const double*, double*, double*) \
      const;                                                                                                       \
  template void Element::law<::refdyn::JacobianScalar>(                                                            \
      const ::refdyn::JacobianScalar&, const ::refdyn::JacobianScalar*, const ::refdyn::JacobianScalar*,           \
      const ::refdyn::JacobianScalar*, ::refdyn::JacobianScalar*, ::refdyn::JacobianScalar*) const;                \
  template void Element::law<::refdyn::ad::Dual<1>>(const ::refdyn::ad::Dual<1>&, const ::refdyn::ad::Dual<1>*,   \
                                                    const ::refdyn::ad::Dual<1>*, const ::refdyn::ad::Dual<1>*,   \
                                                    ::refdyn::ad::Dual<1>*, ::refdyn::ad::Dual<1>*) const;  \
  template void Element::law<::refdyn::Formula>(const ::refdyn::Formula&, const ::refdyn::Formula*,             \
                                                const ::refdyn::Formula*, const ::refdyn::Formula*,             \
                                                ::refdyn::Formula*, ::refdyn::Formula*) const

namespace refdyn::force_detail {

inline void need(bool ok, const std::string& what, const std::string& expected, double got) {
  if (!ok) throw Error(expected_got(what, expected, fmt(got)));
}

}  // namespace refdyn::force_detail
