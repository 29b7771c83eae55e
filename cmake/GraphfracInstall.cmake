# Install rules so an engine can find_package(graphfrac) and link graphfrac::runtime.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)
install(TARGETS graphfrac_runtime EXPORT graphfracTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(DIRECTORY runtime/include/graphfrac DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT graphfracTargets NAMESPACE graphfrac:: FILE graphfracTargets.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/graphfrac)
configure_package_config_file(cmake/graphfracConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/graphfracConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/graphfrac)
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/graphfracConfigVersion.cmake
  COMPATIBILITY SameMajorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/graphfracConfig.cmake
              ${CMAKE_CURRENT_BINARY_DIR}/graphfracConfigVersion.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/graphfrac)
