# Installs the hgdeform build in BUILD_DIR into WORK_DIR/prefix, then configures, builds and
# runs the consumer project in SOURCE_DIR against it.
#   cmake -DBUILD_DIR=... -DSOURCE_DIR=... -DWORK_DIR=... [options] -P run.cmake
# Options:
#   -DSTATIC_FROM=SRC   first configure and build a static libhgdeform (library only) from the
#                       source tree SRC into BUILD_DIR, then install that (the static package)
#   -DTOOLS_DATA=DIR    also run the installed tools (bin/hgdeform --version, and a deform of
#                       DIR/bunny_1839.ply with DIR/bunny_ears.json) with LD_LIBRARY_PATH unset:
#                       they must find libhgdeform through their RPATH, wherever the prefix is
#   -DPYTHON=EXE -DPYTHON_DIR=DIR  also import the installed Python module (PREFIX/DIR/hgdeform)
#                       with EXE from another directory, LD_LIBRARY_PATH unset, and deform with it
#   -DCOMPILER_LAUNCHER=ccache, -DCXX_COMPILER=..., -DC_COMPILER=...  for the static build (the
#                       main build's, so that the library is built like the rest)
foreach(var BUILD_DIR SOURCE_DIR WORK_DIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "run.cmake: ${var} is not set")
  endif()
endforeach()

set(prefix "${WORK_DIR}/prefix")
set(build "${WORK_DIR}/build")
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")

function(step what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc COMMAND_ECHO STDOUT)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "install_consumer: ${what} failed (${rc})")
  endif()
endfunction()

find_program(NINJA ninja)
if(NINJA)
  set(generator -G Ninja)
else()
  set(generator)
endif()

if(DEFINED STATIC_FROM)
  set(launcher)
  if(COMPILER_LAUNCHER)
    set(launcher "-DCMAKE_CXX_COMPILER_LAUNCHER=${COMPILER_LAUNCHER}"
                 "-DCMAKE_C_COMPILER_LAUNCHER=${COMPILER_LAUNCHER}")
  endif()
  foreach(lang CXX C)
    if(${lang}_COMPILER)
      list(APPEND launcher "-DCMAKE_${lang}_COMPILER=${${lang}_COMPILER}")
    endif()
  endforeach()
  # The library only: no tools, no tests (they would double the build time for nothing new).
  step("static configure" "${CMAKE_COMMAND}" -S "${STATIC_FROM}" -B "${BUILD_DIR}" ${generator}
       -DCMAKE_BUILD_TYPE=Release -DBUILD_SHARED_LIBS=OFF -DHGDEFORM_BUILD_TOOLS=OFF
       -DHGDEFORM_BUILD_TESTS=OFF -DHGDEFORM_PYTHON=OFF ${launcher})
  step("static build" "${CMAKE_COMMAND}" --build "${BUILD_DIR}" --target hgdeform -j 2)
endif()

step("install" "${CMAKE_COMMAND}" --install "${BUILD_DIR}" --prefix "${prefix}")

if(DEFINED STATIC_FROM)
  file(GLOB_RECURSE shared_libs "${prefix}/*libhgdeform.so*")
  file(GLOB_RECURSE static_libs "${prefix}/*libhgdeform.a")
  if(shared_libs OR NOT static_libs)
    message(FATAL_ERROR "install_consumer: expected only libhgdeform.a in ${prefix}")
  endif()
endif()
if(EXISTS "${prefix}/include/hgdeform/render.h")
  message(FATAL_ERROR "install_consumer: render.h is installed without its library")
endif()
# The installed headers stand alone: none includes nlohmann/json (a build dependency only), and
# the documented entries are there by the names the README gives.
file(GLOB_RECURSE installed_headers "${prefix}/include/hgdeform/*.h" "${prefix}/include/hgdeform/*.hpp")
foreach(h IN LISTS installed_headers)
  file(STRINGS "${h}" json_lines REGEX "#include[ \t]*[<\"]nlohmann/")
  if(json_lines)
    message(FATAL_ERROR "install_consumer: ${h} includes nlohmann/json: ${json_lines}")
  endif()
endforeach()
foreach(entry hgdeform.h pcl.h)
  if(NOT EXISTS "${prefix}/include/hgdeform/${entry}")
    message(FATAL_ERROR "install_consumer: <hgdeform/${entry}> is not installed")
  endif()
endforeach()

if(DEFINED TOOLS_DATA)
  # An installed program runs from the prefix alone: no LD_LIBRARY_PATH, and the build tree's
  # RPATH must be gone (the prefix is not where the build put it).
  set(tool "${prefix}/bin/hgdeform")
  set(noenv "${CMAKE_COMMAND}" -E env --unset=LD_LIBRARY_PATH)
  execute_process(COMMAND ${noenv} "${tool}" --version RESULT_VARIABLE rc OUTPUT_VARIABLE out
                  ERROR_VARIABLE err)
  if(NOT rc EQUAL 0 OR NOT out MATCHES "^hgdeform [0-9]+\\.[0-9]+\\.[0-9]+")
    message(FATAL_ERROR "install_consumer: ${tool} --version: exit ${rc}, '${out}' ${err}")
  endif()
  message(STATUS "install_consumer: ${out}")
  step("installed hgdeform deform" ${noenv} "${tool}" deform "${TOOLS_DATA}/bunny_1839.ply"
       --scenario "${TOOLS_DATA}/bunny_ears.json" -o "${WORK_DIR}/bunny_deformed.ply"
       --report "${WORK_DIR}/bunny_report.json")
  foreach(f bunny_deformed.ply bunny_report.json)
    file(SIZE "${WORK_DIR}/${f}" size)
    if(NOT size GREATER 0)
      message(FATAL_ERROR "install_consumer: the installed hgdeform wrote no ${f}")
    endif()
  endforeach()
  file(READ "${WORK_DIR}/bunny_report.json" report)
  if(NOT report MATCHES "\"version\"")
    message(FATAL_ERROR "install_consumer: no version in the report: ${report}")
  endif()
  if(DEFINED XVFB_RUN)
    # The renderer is a module the installed program loads from the prefix for a batch report.
    file(REMOVE_RECURSE "${WORK_DIR}/scans" "${WORK_DIR}/batch_out" "${WORK_DIR}/batch_report")
    file(COPY "${TOOLS_DATA}/bunny_1839.ply" DESTINATION "${WORK_DIR}/scans")
    # (Under the sanitizers, Mesa's GL leaks as in batch_thumbnails_xvfb: the same allowances.)
    step("installed hgdeform batch --report" ${noenv} "ASAN_OPTIONS=detect_leaks=0:alloc_dealloc_mismatch=0"
         "${XVFB_RUN}" -a -s "-screen 0 1280x1024x24" "${tool}" batch
         -s "${TOOLS_DATA}/bunny_ears.json" "${WORK_DIR}/scans" -o "${WORK_DIR}/batch_out"
         --report "${WORK_DIR}/batch_report")
    if(NOT EXISTS "${WORK_DIR}/batch_report/thumbs/bunny_1839.ply.png")
      message(FATAL_ERROR "install_consumer: the installed hgdeform batch drew no thumbnail")
    endif()
  endif()
endif()

if(DEFINED PYTHON)
  # The installed package from the prefix alone: its module finds libhgdeform through its RPATH.
  string(CONCAT code "import hgdeform, numpy as np\n"
           "p = np.random.default_rng(1).uniform(0, 1, (500, 3))\n"
           "s = hgdeform.Scenario().fix(hgdeform.Region.box((0, 0, 0), (0.2, 1, 1)))"
           ".manipulate(hgdeform.Region.box((0.8, 0, 0), (1, 1, 1))).frame(translate=(0, 0.1, 0))\n"
           "out, report = hgdeform.deform(p, s)\n"
           "assert hgdeform.__file__.startswith('${prefix}/'), hgdeform.__file__\n"
           "print(hgdeform.__version__, report['points'])\n")
  execute_process(COMMAND "${CMAKE_COMMAND}" -E env --unset=LD_LIBRARY_PATH "PYTHONPATH=${prefix}/${PYTHON_DIR}"
                          "${PYTHON}" -c "${code}"
                  WORKING_DIRECTORY "${WORK_DIR}" RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0 OR NOT out MATCHES "^[0-9]+\\.[0-9]+\\.[0-9]+ 500")
    message(FATAL_ERROR "install_consumer: the installed Python module: exit ${rc}, '${out}' ${err}")
  endif()
  message(STATUS "install_consumer: import hgdeform from the prefix: ${out}")
endif()

step("configure" "${CMAKE_COMMAND}" -S "${SOURCE_DIR}" -B "${build}" ${generator}
     "-DCMAKE_PREFIX_PATH=${prefix}" -DCMAKE_BUILD_TYPE=Release)
step("build" "${CMAKE_COMMAND}" --build "${build}" -j 1)
step("run" "${build}/consumer")
message(STATUS "install_consumer: OK")
