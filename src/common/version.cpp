#include "refdyn/common/version.hpp"

#ifndef REFDYN_VERSION_STRING
#error "REFDYN_VERSION_STRING is set by src/CMakeLists.txt from project(VERSION)"
#endif

namespace refdyn {

const char* version() { return REFDYN_VERSION_STRING; }

}  // namespace refdyn
