# `cmake --install BUILD --prefix P`: the embedding package (docs/embedding.md) and nothing else:
#   P/include/lfgi/runtime.h + runtime_vulkan.h, P/lib/liblfgi_runtime.so*, P/share/lfgi/shaders/*.spv (found beside the
#   library at run time, gpu/program.cpp shaderDirectory), P/lib/cmake/lfgi/ (lfgiConfig.cmake, version
#   file, exported target lfgi::runtime). The command-line tools, benches and the offline bake (Embree,
#   libtorch) are not installed.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)
set(LFGI_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/lfgi)
install(TARGETS lfgi_runtime EXPORT lfgiTargets
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(FILES ${PROJECT_SOURCE_DIR}/include/lfgi/runtime.h ${PROJECT_SOURCE_DIR}/include/lfgi/runtime_vulkan.h
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/lfgi)
install(DIRECTORY ${LFGI_SPIRV_DIR}/ DESTINATION ${CMAKE_INSTALL_DATADIR}/lfgi/shaders
        FILES_MATCHING PATTERN "*.spv")
install(EXPORT lfgiTargets NAMESPACE lfgi:: DESTINATION ${LFGI_INSTALL_CMAKEDIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/lfgiConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/lfgiConfig.cmake INSTALL_DESTINATION ${LFGI_INSTALL_CMAKEDIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/lfgiConfigVersion.cmake VERSION ${PROJECT_VERSION}
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/lfgiConfig.cmake ${PROJECT_BINARY_DIR}/lfgiConfigVersion.cmake
        DESTINATION ${LFGI_INSTALL_CMAKEDIR})
