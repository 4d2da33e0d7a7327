# `cmake --install BUILD [--prefix P]` (GNUInstallDirs): the header, the shared
# library libbootsurf.so.MAJOR (+ VERSION and development symlinks), the static
# library libbootsurf.a, bootsurf.pc, the CMake package (find_package(bootsurf)
# gives bootsurf::bootsurf, the shared library, and bootsurf::bootsurf_static),
# the command line and its man page (made from its own --help). tests/cli/
# library.sh installs into a temporary prefix and builds examples/ against it.
include(CMakePackageConfigHelpers)

set(BSURF_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/bootsurf)

install(TARGETS bootsurf bootsurf_shared EXPORT bootsurfTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS bootsurf_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(FILES ${PROJECT_SOURCE_DIR}/include/bootsurf.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})

install(EXPORT bootsurfTargets NAMESPACE bootsurf:: DESTINATION ${BSURF_CMAKE_DIR})
set(BSURF_CONFIG_OPENMP ${OpenMP_C_FOUND})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/bootsurfConfig.cmake.in
  ${PROJECT_BINARY_DIR}/bootsurfConfig.cmake INSTALL_DESTINATION ${BSURF_CMAKE_DIR})
# 0.x: the SONAME is libbootsurf.so.0; a new major version is a new ABI.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/bootsurfConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMajorVersion)
install(FILES ${PROJECT_BINARY_DIR}/bootsurfConfig.cmake
  ${PROJECT_BINARY_DIR}/bootsurfConfigVersion.cmake DESTINATION ${BSURF_CMAKE_DIR})

# pkg-config: `pkg-config --cflags --libs bootsurf` links the shared library;
# `--static` adds what libbootsurf.a needs.
if(OpenMP_C_FOUND)
  set(BSURF_PC_OPENMP "${OpenMP_C_FLAGS}")
else()
  set(BSURF_PC_OPENMP "")
endif()
# The prefix is found from the .pc file's own place (${pcfiledir}), so the
# package can be installed with `cmake --install --prefix ANYWHERE`.
if(IS_ABSOLUTE "${CMAKE_INSTALL_LIBDIR}")
  set(BSURF_PC_PREFIX "${CMAKE_INSTALL_PREFIX}")
  set(BSURF_PC_LIBDIR "${CMAKE_INSTALL_LIBDIR}")
else()
  file(RELATIVE_PATH _up "/root/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/root")
  set(BSURF_PC_PREFIX "\${pcfiledir}/${_up}")
  set(BSURF_PC_LIBDIR "\${prefix}/${CMAKE_INSTALL_LIBDIR}")
endif()
if(IS_ABSOLUTE "${CMAKE_INSTALL_INCLUDEDIR}")
  set(BSURF_PC_INCLUDEDIR "${CMAKE_INSTALL_INCLUDEDIR}")
else()
  set(BSURF_PC_INCLUDEDIR "\${prefix}/${CMAKE_INSTALL_INCLUDEDIR}")
endif()
configure_file(${PROJECT_SOURCE_DIR}/cmake/bootsurf.pc.in ${PROJECT_BINARY_DIR}/bootsurf.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/bootsurf.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

# bootsurf(1) from the built command's own --help and every command's, so the
# manual never drifts from the program.
add_custom_command(OUTPUT ${PROJECT_BINARY_DIR}/bootsurf.1
  COMMAND ${CMAKE_COMMAND} -DBSURF=$<TARGET_FILE:bootsurf_cli> -DVERSION=${PROJECT_VERSION}
          -DOUT=${PROJECT_BINARY_DIR}/bootsurf.1 -P ${PROJECT_SOURCE_DIR}/cmake/manpage.cmake
  DEPENDS bootsurf_cli ${PROJECT_SOURCE_DIR}/cmake/manpage.cmake
  COMMENT "Generating the man page bootsurf.1 from bootsurf --help")
add_custom_target(bootsurf_manpage ALL DEPENDS ${PROJECT_BINARY_DIR}/bootsurf.1)
install(FILES ${PROJECT_BINARY_DIR}/bootsurf.1 DESTINATION ${CMAKE_INSTALL_MANDIR}/man1)
