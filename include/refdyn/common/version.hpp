// refdyn's version: the project(VERSION) of the top-level CMakeLists.txt, recorded in
// CHANGELOG.md. Printed by `refdyn --version` and written to summary.json ("refdyn_version").
#pragma once

namespace refdyn {

/// "MAJOR.MINOR.PATCH", e.g. "0.2.0".
const char* version();

}  // namespace refdyn
