// Linked into every executable of a sanitizer build (REFDYN_SANITIZE, REFDYN_FUZZ): the
// LeakSanitizer suppressions of cmake/lsan.supp, built in so that no environment variable is
// needed (e.g. when gtest_discover_tests runs the tests at build time).
extern "C" const char* __lsan_default_suppressions() {
  // CLN (GiNaC's number library, a system library) leaks 26 bytes in a static initializer;
  // GiNaC leaks 40 bytes when a division by zero throws (tests/data/fuzz/README.md); when the
  // throwing evaluation runs in GiNaC's header templates (dynallocate, compiled into our code),
  // the frames are ours by address, so they are named too.
  return "leak:libcln.so\nleak:libginac.so\nleak:GiNaC::dynallocate\n";
}

// Do not print the "Suppressions used" statistics at exit: it would add lines to stderr, which
// the CLI tests check to be exactly one line.
extern "C" const char* __lsan_default_options() { return "print_suppressions=0"; }
