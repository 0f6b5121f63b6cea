# What `cmake --install build --prefix P` puts in P: the libraries and their public headers
# (include/bloomref/...), the bloomref command, the OpenImageIO module the I/O library loads on
# first use, a CMake package (find_package(bloomref CONFIG) -> bloomref::<library> targets with
# their dependencies found) and a pkg-config file. The headers under each library's src/ stay
# private. The commands' library is bloomref::check (`bloomref check` as a library: check/check.h
# under include/bloomref/cli/), with the Vulkan path it calls; the pkg-config file does not
# name them.
include(CMakePackageConfigHelpers)

# Every library a consumer may link, with the name it has in the package (bloomref::runtime).
# bloomref_cpu_flags carries no usage requirement out of the package (its compile options are
# private to each library) but is named by their link interfaces, so it is exported too.
set(bloomref_installed_libraries machinery simd exact reference engine engine_internal runtime io tools gpu parity cpu_flags)
set(bloomref_installed_targets)
foreach(name ${bloomref_installed_libraries})
  set_target_properties(bloomref_${name} PROPERTIES EXPORT_NAME ${name})
  list(APPEND bloomref_installed_targets bloomref_${name})
endforeach()
# The component `check` (find_package(bloomref COMPONENTS check)): its own export set, so that
# a consumer of the others needs none of its dependencies (Vulkan, SPIRV-Cross, CLI11, JSON).
set_target_properties(bloomref_vulkan PROPERTIES EXPORT_NAME vulkan)
set_target_properties(bloomref_batch PROPERTIES EXPORT_NAME batch)
set_target_properties(bloomref_cli PROPERTIES EXPORT_NAME check)
install(TARGETS bloomref_vulkan bloomref_batch bloomref_cli EXPORT bloomrefCheckTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})

install(TARGETS ${bloomref_installed_targets} EXPORT bloomrefTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS bloomref RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(TARGETS bloomref_oiio LIBRARY DESTINATION ${BLOOMREF_OIIO_MODULE_INSTALL_DIR})
foreach(folder machinery reference engine runtime io tools gpu vulkan parity)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${folder}/include/bloomref
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} FILES_MATCHING PATTERN "*.h")
endforeach()
install(DIRECTORY ${PROJECT_SOURCE_DIR}/cli/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/bloomref/cli
        FILES_MATCHING PATTERN "*.h")

set(bloomref_cmake_dir ${CMAKE_INSTALL_LIBDIR}/cmake/bloomref)
install(EXPORT bloomrefTargets NAMESPACE bloomref:: DESTINATION ${bloomref_cmake_dir})
install(EXPORT bloomrefCheckTargets NAMESPACE bloomref:: DESTINATION ${bloomref_cmake_dir})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/bloomrefConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/bloomrefConfig.cmake
                              INSTALL_DESTINATION ${bloomref_cmake_dir})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/bloomrefConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/bloomrefConfig.cmake
              ${PROJECT_BINARY_DIR}/bloomrefConfigVersion.cmake
        DESTINATION ${bloomref_cmake_dir})

# pkg-config: the libraries are static, so what they link is listed for every consumer
# (Requires, Libs), not only for `pkg-config --static`. Paths are relative to the .pc file's
# folder, so the installation may move.
file(RELATIVE_PATH bloomref_pc_to_prefix /prefix/${CMAKE_INSTALL_LIBDIR}/pkgconfig /prefix)
string(REGEX REPLACE "/$" "" bloomref_pc_to_prefix "${bloomref_pc_to_prefix}")
set(bloomref_pc_dl_libs)
foreach(lib ${CMAKE_DL_LIBS})
  string(APPEND bloomref_pc_dl_libs " -l${lib}")
endforeach()
configure_file(${PROJECT_SOURCE_DIR}/cmake/bloomref.pc.in ${PROJECT_BINARY_DIR}/bloomref.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/bloomref.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
