# Writes OUT: apps/report_template.html with the vendored JavaScript libraries inlined
# (refdyn report: one self-contained HTML file, nothing fetched at view time).
#   -DTEMPLATE=apps/report_template.html -DOUT=<build>/report_template.html
#   -DTHREE_JS=.../three.min.js -DORBIT_JS=.../OrbitControls.js
#   -DDYGRAPH_JS=.../dygraph.min.js -DDYGRAPH_CSS=.../dygraph.min.css
#   -DSTL_LOADER=.../STLLoader.js -DOBJ_LOADER=.../OBJLoader.js -DCOLLADA_LOADER=.../ColladaLoader.js
# When a library is missing (empty path) OUT holds only the marker REFDYN_REPORT_UNAVAILABLE and
# `refdyn report` explains how to get the libraries.
foreach(v THREE_JS ORBIT_JS DYGRAPH_JS DYGRAPH_CSS STL_LOADER OBJ_LOADER COLLADA_LOADER)
  if(NOT ${v} OR NOT EXISTS "${${v}}")
    file(WRITE "${OUT}" "REFDYN_REPORT_UNAVAILABLE")
    return()
  endif()
endforeach()
file(READ "${TEMPLATE}" html)
foreach(v THREE_JS ORBIT_JS DYGRAPH_JS DYGRAPH_CSS STL_LOADER OBJ_LOADER COLLADA_LOADER)
  file(READ "${${v}}" content)
  string(FIND "${content}" "</script" closing)
  string(FIND "${content}" "</style" closing_style)
  if(NOT closing EQUAL -1 OR NOT closing_style EQUAL -1)
    message(FATAL_ERROR "${${v}} contains '</script' or '</style': it cannot be inlined as is")
  endif()
  string(REPLACE "@@${v}@@" "${content}" html "${html}")
endforeach()
file(WRITE "${OUT}" "${html}")
