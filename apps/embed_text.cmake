# Writes OUT: a C++ source defining refdyn::app::kPaperScenarioYaml with the bytes of IN
# (as hex escapes, so any content survives).
file(READ ${IN} HEX HEX)
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "\\\\x\\1" ESCAPED "${HEX}")
file(WRITE ${OUT} "// Generated from ${IN}; do not edit.\nnamespace refdyn::app {\nextern const char* const kPaperScenarioYaml;\nconst char* const kPaperScenarioYaml = \"${ESCAPED}\";\n}  // namespace refdyn::app\n")
