#pragma once
// Where the tests find the sources and the refdyn executable. The paths are compiled into
// test_support.cpp only (tests/CMakeLists.txt), so every test object is the same in any clone
// or worktree (a compiler cache can share them); each test file sees these through the forced
// include `-include test_paths.hpp`.
extern "C" const char* refdyn_test_source_dir();
extern "C" const char* refdyn_test_cli();
#define REFDYN_SOURCE_DIR (refdyn_test_source_dir())
#define REFDYN_CLI (refdyn_test_cli())
