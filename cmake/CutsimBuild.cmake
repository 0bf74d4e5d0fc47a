# Build speed and target CPU, included by the top-level CMakeLists.txt (docs/build.md):
#   CUTSIM_ARCH         instruction set: portable (x86-64-v2), native, or any -march value
#   CUTSIM_CCACHE       compile through ccache when it is installed
#   CUTSIM_FAST_LINKER  link with mold or lld when the compiler can use one
#   CUTSIM_PCH          precompiled third-party headers (Eigen, JSON, Bullet, CLI11, GoogleTest)
#   CUTSIM_UNITY        the command's sources and each test program compiled in a few batches
include(CheckCXXCompilerFlag)
include(CheckLinkerFlag)

set(CUTSIM_ARCH "portable" CACHE STRING
    "Instruction set: portable (x86-64-v2 on x86-64, the compiler's default elsewhere), native (this machine's CPU), or a -march value such as x86-64-v3")
set_property(CACHE CUTSIM_ARCH PROPERTY STRINGS portable native x86-64-v2 x86-64-v3 x86-64-v4)
if(DEFINED CUTSIM_NATIVE)
  message(WARNING "CUTSIM_NATIVE is gone: use -DCUTSIM_ARCH=native (or portable)")
  if(CUTSIM_NATIVE)
    set(CUTSIM_ARCH native CACHE STRING "" FORCE)
  endif()
  unset(CUTSIM_NATIVE CACHE)
endif()

# -march for every target (CUTSIM_MARCH_FLAG, also asked of code built against the installed
# libraries); none under the sanitizers (their builds check code, not speed) or for
# the fuzz targets, and none for portable off x86-64.
function(cutsim_set_arch)
  if(CUTSIM_SANITIZE OR CUTSIM_FUZZ OR CUTSIM_ARCH STREQUAL "")
    return()
  endif()
  set(march ${CUTSIM_ARCH})
  if(march STREQUAL "portable")
    if(NOT CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$")
      return()
    endif()
    set(march x86-64-v2)
  endif()
  check_cxx_compiler_flag(-march=${march} CUTSIM_MARCH_OK_${march})
  if(NOT CUTSIM_MARCH_OK_${march})
    message(FATAL_ERROR "CUTSIM_ARCH=${CUTSIM_ARCH}: the compiler refuses -march=${march}")
  endif()
  add_compile_options(-march=${march})
  # for code built against the installed libraries: Eigen's alignment follows the instruction set
  set(CUTSIM_MARCH_FLAG -march=${march} PARENT_SCOPE)
  message(STATUS "cutsim: -march=${march} (CUTSIM_ARCH=${CUTSIM_ARCH})")
endfunction()

# ccache with the source folder as its base: paths below it are hashed relative, so a clone in
# another folder hits the same cache entries. Debug info names the source folder as ".", so that
# builds with -g are shared too (ccache then leaves the working directory out of the hash).
option(CUTSIM_CCACHE "Compile through ccache when it is installed" ON)
function(cutsim_set_ccache)
  if(NOT CUTSIM_CCACHE OR CMAKE_CXX_COMPILER_LAUNCHER)
    return()
  endif()
  find_program(CUTSIM_CCACHE_PROGRAM ccache)
  if(NOT CUTSIM_CCACHE_PROGRAM)
    return()
  endif()
  # pch_defines, time_macros: what ccache needs to cache compilations that use a PCH
  set(CMAKE_CXX_COMPILER_LAUNCHER
      ${CMAKE_COMMAND} -E env CCACHE_BASEDIR=${PROJECT_SOURCE_DIR}
      CCACHE_SLOPPINESS=pch_defines,time_macros,include_file_mtime,include_file_ctime ${CUTSIM_CCACHE_PROGRAM}
      PARENT_SCOPE)
  add_compile_options(-fdebug-prefix-map=${PROJECT_SOURCE_DIR}=.)
  message(STATUS "cutsim: compiling through ${CUTSIM_CCACHE_PROGRAM}")
endfunction()

# mold, else lld: GNU ld takes seconds per test program on the static libraries
option(CUTSIM_FAST_LINKER "Link with mold or lld when the compiler can use one" ON)
function(cutsim_set_linker)
  if(NOT CUTSIM_FAST_LINKER)
    return()
  endif()
  foreach(ld mold lld)
    check_linker_flag(CXX -fuse-ld=${ld} CUTSIM_LINKER_${ld})
    if(CUTSIM_LINKER_${ld})
      add_link_options(-fuse-ld=${ld})
      message(STATUS "cutsim: linking with ${ld}")
      return()
    endif()
  endforeach()
endfunction()

option(CUTSIM_PCH "Precompile the third-party headers most sources include" ON)
# Third-party headers only: they never change with the project, and name no path of the checkout
# (cached compilations stay valid in another clone).
# CUTSIM_PCH_EIGEN for the physics library (every file includes Eigen, few JSON or Bullet), the core
# list for the command, the harnesses and the tests.
set(CUTSIM_PCH_EIGEN <algorithm> <cmath> <memory> <string> <vector> <Eigen/Core> <Eigen/Geometry>)
set(CUTSIM_PCH_CORE ${CUTSIM_PCH_EIGEN} <cstdio> <nlohmann/json.hpp>)
# cutsim_pch(TARGET [HEADER ...]): TARGET gets the core headers and the extra ones precompiled
function(cutsim_pch target)
  if(CUTSIM_PCH)
    target_precompile_headers(${target} PRIVATE ${CUTSIM_PCH_CORE} ${ARGN})
  endif()
endfunction()
# cutsim_pch_reuse(TARGET FROM): TARGET uses FROM's precompiled headers (same compile flags)
function(cutsim_pch_reuse target from)
  if(CUTSIM_PCH)
    target_precompile_headers(${target} REUSE_FROM ${from})
  endif()
endfunction()

# Unity builds: the command's files and each test program's files share their template
# instantiations (nlohmann/json, CLI11, GoogleTest, Eigen) when compiled a few files at a time.
option(CUTSIM_UNITY "Compile the command's sources and the test programs in batches (unity build)" ON)
# cutsim_unity(TARGET BATCH): TARGET's .cpp files compiled in batches of at most BATCH files, of
# equal size. The batch files include the sources by their path relative to the batch file (CMake's
# UNITY_BUILD writes absolute paths), so that ccache hits them from a clone in another folder too.
function(cutsim_unity target batch)
  if(NOT CUTSIM_UNITY)
    return()
  endif()
  get_target_property(sources ${target} SOURCES)
  list(FILTER sources INCLUDE REGEX "\\.cpp$")
  list(LENGTH sources n)
  math(EXPR batches "(${n} + ${batch} - 1) / ${batch}")
  set(dir ${CMAKE_CURRENT_BINARY_DIR}/unity)
  set(i 0)
  foreach(src ${sources})
    math(EXPR b "${i} * ${batches} / ${n}")
    get_filename_component(abs ${src} ABSOLUTE)
    file(RELATIVE_PATH rel ${dir} ${abs})
    string(APPEND text_${b} "#include \"${rel}\"\n")
    set_source_files_properties(${src} PROPERTIES HEADER_FILE_ONLY ON)
    math(EXPR i "${i} + 1")
  endforeach()
  math(EXPR last "${batches} - 1")
  foreach(b RANGE ${last})
    file(CONFIGURE OUTPUT ${dir}/${target}_${b}.cpp CONTENT "${text_${b}}")
    target_sources(${target} PRIVATE ${dir}/${target}_${b}.cpp)
  endforeach()
endfunction()
