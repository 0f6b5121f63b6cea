# Installs the build into a fresh prefix, then builds examples/consumer out of tree against it,
# twice: through the CMake package (find_package(bloomref)) and through pkg-config
# (bloomref.pc). Each program runs a bloom and checks its values (examples/consumer/main.cpp).
#   cmake -DBUILD=<build dir> -DSOURCE=<source dir> -DWORK=<scratch dir> -DGENERATOR=<gen>
#         -DCXX=<compiler> -P install_consumer.cmake
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
