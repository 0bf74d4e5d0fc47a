# The installed package as a user's project sees it: `cmake --install` into a fresh prefix, the
# example examples/embed configured and built against it from its own folder, then run on
# bar_sag.json. cmake -DBUILD=... -DSOURCE=... -DWORK=... -DLIBDIR=lib [-DCOMPILER=...] [-DLAUNCHER=...] -P embed.cmake
foreach(v BUILD SOURCE WORK LIBDIR)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "embed.cmake: -D${v}=... missing")
  endif()
endforeach()
file(REMOVE_RECURSE ${WORK})
function(run what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "${what} failed (${code}):\n${out}\n${err}")
  endif()
  set(out "${out}" PARENT_SCOPE)
endfunction()

run("cmake --install" ${CMAKE_COMMAND} --install ${BUILD} --prefix ${WORK}/prefix)
foreach(f include/cutsim/sim/simulation.hpp include/cutsim/sim/scene.hpp include/cutsim/cut/xfem.hpp
          ${LIBDIR}/cmake/cutsim/cutsimConfig.cmake ${LIBDIR}/pkgconfig/cutsim.pc)
  if(NOT EXISTS ${WORK}/prefix/${f})
    message(FATAL_ERROR "cmake --install put no ${f} under the prefix")
  endif()
endforeach()

# pkg-config, from the prefix the package was installed into
find_program(PKG_CONFIG pkg-config)
if(PKG_CONFIG)
  set(ENV{PKG_CONFIG_PATH} ${WORK}/prefix/${LIBDIR}/pkgconfig)
  run("pkg-config cutsim" ${PKG_CONFIG} --cflags --libs cutsim)
  string(STRIP "${out}" pc)
  string(REGEX MATCH "-I[^ ]*include/cutsim" inc "${pc}")
  string(REPLACE "-I" "" inc "${inc}")
  if(NOT pc MATCHES "-lcutsim_physics" OR NOT EXISTS ${inc}/sim/simulation.hpp)
    message(FATAL_ERROR "pkg-config --cflags --libs cutsim: ${pc}")
  endif()
endif()

set(args -S ${SOURCE}/examples/embed -B ${WORK}/build -DCMAKE_PREFIX_PATH=${WORK}/prefix -DCMAKE_BUILD_TYPE=Release)
if(COMPILER)
  list(APPEND args -DCMAKE_CXX_COMPILER=${COMPILER})
endif()
if(LAUNCHER)
  list(APPEND args -DCMAKE_CXX_COMPILER_LAUNCHER=${LAUNCHER})
endif()
run("configuring examples/embed against the installed package" ${CMAKE_COMMAND} ${args})
run("building examples/embed" ${CMAKE_COMMAND} --build ${WORK}/build)

# bar_sag: a 1 m x 0.1 m x 0.1 m box of 40 x 4 x 4 cells, 6 tets a cell (Kuhn split): 41 * 5 * 5 =
# 1025 nodes, 3840 elements; the plane x = 0.51 crosses the 16 cells between x = 0.5 and 0.525.
run("cutsim_embed" ${WORK}/build/cutsim_embed ${SOURCE}/assets/scenes/bar_sag.json 20)
message("${out}")
set(num "[0-9.]+e[-+][0-9]+")
foreach(expect "1025 nodes, 3840 elements" "cut: 96 elements crossed"
               "before the cut: stable step exact ${num} s, certified ${num} s"
               "after the cut: stable step exact ${num} s" "after 40 steps: running")
  if(NOT out MATCHES "${expect}")
    message(FATAL_ERROR "cutsim_embed's output lacks '${expect}'")
  endif()
endforeach()
# the step used keeps below the exact limit, before and after the cut
string(REGEX MATCHALL "exact ${num} s, certified ${num} s, step used ${num} s" lines "${out}")
foreach(line ${lines})
  string(REGEX MATCHALL "${num}" v "${line}")
  list(GET v 0 exact)
  list(GET v 2 used)
  if(NOT exact GREATER 0 OR NOT used GREATER 0 OR used GREATER exact)
    message(FATAL_ERROR "cutsim_embed: step ${used} s against the exact limit ${exact} s")
  endif()
endforeach()
