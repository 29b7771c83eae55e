# Install rules so an engine can find_package(graphfrac) and link graphfrac::runtime.
# tests/install checks them end to end (install, configure, build and run a consumer).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)
set(GF_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/graphfrac)
install(TARGETS graphfrac_runtime EXPORT graphfracTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
        # Also set here: this file is included after runtime/, so on a first configure the
        # $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}> there expands to nothing.
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY runtime/include/graphfrac DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT graphfracTargets NAMESPACE graphfrac:: FILE graphfracTargets.cmake
        DESTINATION ${GF_INSTALL_CMAKEDIR})
# A runtime built with the CUDA backend links the static CUDA runtime (gpu/CMakeLists.txt).
if(NOT GF_RUNTIME_NEEDS_CUDA)
  set(GF_RUNTIME_NEEDS_CUDA OFF)
endif()
configure_package_config_file(cmake/graphfracConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/graphfracConfig.cmake
  INSTALL_DESTINATION ${GF_INSTALL_CMAKEDIR})
# 0.x: minor versions may break the API, so only the same major.minor is compatible.
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/graphfracConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/graphfracConfig.cmake
              ${CMAKE_CURRENT_BINARY_DIR}/graphfracConfigVersion.cmake
        DESTINATION ${GF_INSTALL_CMAKEDIR})
