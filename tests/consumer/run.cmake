# CTest test install_consumer: installs the build tree into a temporary prefix, then configures,
# builds and runs tests/consumer (find_package(refdyn REQUIRED)) against it, with the
# compiler's default flags (no -march=native). Run as
#   cmake -DBUILD_DIR=... -DSOURCE_DIR=... -DWORK_DIR=... -DCXX=... [-DEXTRA_FLAGS=...]
#         [-DCHECK_NO_AVX=ON] -P run.cmake
foreach(v BUILD_DIR SOURCE_DIR WORK_DIR CXX)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "run.cmake: -D${v}=... missing")
  endif()
endforeach()

function(run_step what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "install_consumer: ${what} failed (${rc}):\n${out}\n${err}")
  endif()
  set(STEP_OUTPUT "${out}" PARENT_SCOPE)
endfunction()

set(prefix ${WORK_DIR}/prefix)
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})

run_step("cmake --install" ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
foreach(f include/refdyn/multibody/model.hpp include/refdyn/multibody/recursive_dynamics.hpp include/refdyn/multibody/kinematics.hpp
          include/refdyn/io/scenario.hpp lib/cmake/refdyn/refdynConfig.cmake
          lib/cmake/refdyn/refdynConfigVersion.cmake lib/cmake/refdyn/refdynTargets.cmake)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "install_consumer: ${prefix}/${f} was not installed")
  endif()
endforeach()
file(GLOB libs ${prefix}/lib/librefdyn_core.a ${prefix}/lib/*/librefdyn_core.a)
if(NOT libs)
  message(FATAL_ERROR "install_consumer: librefdyn_core.a was not installed under ${prefix}/lib")
endif()
# Nothing exported may force the library's instruction set on its users.
file(GLOB exported ${prefix}/lib/cmake/refdyn/refdynTargets*.cmake ${prefix}/lib/*/cmake/refdyn/refdynTargets*.cmake)
foreach(f ${exported})
  file(READ ${f} text)
  if(text MATCHES "march")
    message(FATAL_ERROR "install_consumer: ${f} exports an -march flag")
  endif()
endforeach()

run_step("configure consumer" ${CMAKE_COMMAND} -S ${SOURCE_DIR}/tests/consumer -B ${WORK_DIR}/build
         -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_CXX_COMPILER=${CXX} -DCMAKE_BUILD_TYPE=Release
         "-DCMAKE_CXX_FLAGS=${EXTRA_FLAGS}" "-DCMAKE_EXE_LINKER_FLAGS=${EXTRA_FLAGS}")
run_step("build consumer" ${CMAKE_COMMAND} --build ${WORK_DIR}/build -j 2)

if(EXTRA_FLAGS MATCHES "sanitize")  # CLN's one static-initializer leak is not refdyn's
  set(ENV{LSAN_OPTIONS} "suppressions=${SOURCE_DIR}/cmake/lsan.supp")
endif()
foreach(exe consumer consumer_io consumer_all)
  run_step("run ${exe}" ${WORK_DIR}/build/${exe})
  message(STATUS "${exe}: ${STEP_OUTPUT}")
  if(NOT STEP_OUTPUT MATCHES "refdyn consumer: OK")
    message(FATAL_ERROR "install_consumer: ${exe} did not report OK: ${STEP_OUTPUT}")
  endif()
  if(CHECK_NO_AVX AND NOT STEP_OUTPUT MATCHES "AVX=0")
    message(FATAL_ERROR "install_consumer: the consumer was meant to be built without AVX: ${STEP_OUTPUT}")
  endif()
endforeach()
file(REMOVE_RECURSE ${WORK_DIR})
