# Installs the build into a fresh prefix, then builds examples/consumer out of tree against it,
# twice: through the CMake package (find_package(bloomref)) and through pkg-config
# (bloomref.pc). Each program runs a bloom and checks its values (examples/consumer/main.cpp);
# through the package, a second judges stages in memory with bloomref::check
# (examples/consumer/check_main.cpp).
# With PYTHON and PYTHON_DIR (the module's folder in the prefix), the installed module is
# imported from there and runs a bloom.
#   cmake -DBUILD=<build dir> -DSOURCE=<source dir> -DWORK=<scratch dir> -DGENERATOR=<gen>
#         -DCXX=<compiler> [-DPYTHON=<python3> -DPYTHON_DIR=<dir>] -P install_consumer.cmake
foreach(v BUILD SOURCE WORK CXX)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "install_consumer.cmake needs -D${v}=...")
  endif()
endforeach()

function(run what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} failed (${rc}):\n${out}\n${err}")
  endif()
  message(STATUS "${what}: ok")
  set(last_output "${out}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE ${WORK})
set(prefix ${WORK}/prefix)
run("cmake --install into ${prefix}" ${CMAKE_COMMAND} --install ${BUILD} --prefix ${prefix})

# The CMake package, from a project that knows nothing of the build tree.
set(generator_args)
if(GENERATOR)
  set(generator_args -G ${GENERATOR})
endif()
run("configure examples/consumer" ${CMAKE_COMMAND} -S ${SOURCE}/examples/consumer -B ${WORK}/consumer
    ${generator_args} -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=${CXX}
    -DCMAKE_PREFIX_PATH=${prefix})
run("build examples/consumer" ${CMAKE_COMMAND} --build ${WORK}/consumer)
run("run the consumer (CMake package)" ${WORK}/consumer/bloomref_consumer ${WORK}/consumer/out.exr)
message(STATUS "${last_output}")
run("run the check consumer (CMake package)" ${WORK}/consumer/bloomref_check_consumer)
message(STATUS "${last_output}")

# pkg-config: the same program from the compiler's command line.
find_program(PKG_CONFIG pkg-config REQUIRED)
set(ENV{PKG_CONFIG_PATH} ${prefix}/lib/pkgconfig)
run("pkg-config bloomref" ${PKG_CONFIG} --cflags --libs bloomref)
string(STRIP "${last_output}" flags)
separate_arguments(flags UNIX_COMMAND "${flags}")
run("compile with pkg-config's flags" ${CXX} -std=c++17 -O1 ${SOURCE}/examples/consumer/main.cpp
    -o ${WORK}/consumer_pc ${flags})
run("run the consumer (pkg-config)" ${WORK}/consumer_pc)
message(STATUS "${last_output}")

if(PYTHON AND PYTHON_DIR)
  set(ENV{PYTHONPATH} ${prefix}/${PYTHON_DIR})
  run("the installed Python module" ${PYTHON} -c [=[
import numpy as np, os, sys, bloomref
assert bloomref.__file__.startswith(sys.argv[1]), bloomref.__file__
out = bloomref.run(np.full((8, 8, 4), 0.5, np.float32), gamma=1.0)
expected = 1.0 - np.exp(-0.5)
assert abs(float(out[0, 0, 0]) - expected) < 1e-6, out[0, 0]
print("bloomref", bloomref.__version__, "from", bloomref.__file__, "ok")
]=] ${prefix})
  message(STATUS "${last_output}")
endif()
