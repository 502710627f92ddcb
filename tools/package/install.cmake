# Installation: `cmake --install build [--prefix P]` puts
#   bin/pamc
#   share/pamc/od/            the EDS files, od/rigs/ (rig files), od/profile/ (device EDS of the examples)
#   include/pamc/<module>/    the headers of pamc::model, pamc::estimation, pamc::control, pamc::canopen,
#                             pamc::canopen_socketcan
#   lib/libpamc_*.a, lib/cmake/pamc/   the libraries and find_package(pamc) with namespaced targets
#   lib/systemd/system/pamc-controller@.service   the controller as a real-time service per interface
#   share/bash-completion/completions/pamc        the bash completion, generated from pamc's option tables
#   lib/python3/dist-packages/pamc/               the Python module with its type stubs (python/CMakeLists.txt)
# and `cpack -G DEB` (in the build folder) makes a Debian package of the same.
include(CMakePackageConfigHelpers)

install(TARGETS pamc RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/od/ DESTINATION ${CMAKE_INSTALL_DATADIR}/pamc/od)
install(FILES ${PROJECT_BINARY_DIR}/pamc.bash DESTINATION ${CMAKE_INSTALL_DATADIR}/bash-completion/completions
        RENAME pamc)

set(PAMC_LIBRARIES pamc_model pamc_estimation pamc_control pamc_canopen pamc_canopen_socketcan)
install(TARGETS ${PAMC_LIBRARIES} EXPORT pamcTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/pamc)
foreach(m model estimation control)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/src/${m}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/pamc/${m}
          FILES_MATCHING PATTERN "*.hpp" PATTERN "*.inc")
endforeach()
install(DIRECTORY ${PROJECT_SOURCE_DIR}/canopen/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/pamc/canopen
        FILES_MATCHING PATTERN "*.hpp")

set(PAMC_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/pamc)
install(EXPORT pamcTargets NAMESPACE pamc:: DESTINATION ${PAMC_CMAKE_DIR})
configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/pamcConfig.cmake.in ${PROJECT_BINARY_DIR}/pamcConfig.cmake
                              INSTALL_DESTINATION ${PAMC_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/pamcConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/pamcConfig.cmake ${PROJECT_BINARY_DIR}/pamcConfigVersion.cmake
        DESTINATION ${PAMC_CMAKE_DIR})

# The service: one instance per CAN interface, pamc-controller@can0.service; its settings in
# /etc/pamc/<interface>.conf (the rig file and the bit rate).
set(PAMC_BIN ${CMAKE_INSTALL_FULL_BINDIR}/pamc)
configure_file(${CMAKE_CURRENT_LIST_DIR}/pamc-controller@.service.in ${PROJECT_BINARY_DIR}/pamc-controller@.service @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/pamc-controller@.service DESTINATION lib/systemd/system)
install(FILES ${CMAKE_CURRENT_LIST_DIR}/pamc-example.conf DESTINATION ${CMAKE_INSTALL_DATADIR}/pamc)

set(CPACK_PACKAGE_NAME pamc)
set(CPACK_PACKAGE_VENDOR "pamc")
set(CPACK_PACKAGE_CONTACT "pamc maintainers <pamc@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "Pneumatic artificial muscle controller as a CANopen node (UKF + active model control)")
set(CPACK_DEBIAN_PACKAGE_DEPENDS "libinih1, libc6, libstdc++6, can-utils, iproute2")
if(PAMC_WITH_PYTHON)
  # The module is built for one Python minor version (its ABI) and returns numpy arrays.
  execute_process(COMMAND ${PAMC_PYTHON} -c "import sys; v = sys.version_info; print(f'{v[0]}.{v[1]};{v[0]}.{v[1] + 1}')"
                  OUTPUT_VARIABLE PAMC_PY_VERSIONS OUTPUT_STRIP_TRAILING_WHITESPACE)
  list(GET PAMC_PY_VERSIONS 0 PAMC_PY_THIS)
  list(GET PAMC_PY_VERSIONS 1 PAMC_PY_NEXT)
  set(CPACK_DEBIAN_PACKAGE_DEPENDS
      "${CPACK_DEBIAN_PACKAGE_DEPENDS}, python3 (>= ${PAMC_PY_THIS}), python3 (<< ${PAMC_PY_NEXT}), python3-numpy")
endif()
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
include(CPack)
