# lfgi_add_shaders(TARGET SOURCES a.comp b.comp ...)
# Compiles GLSL to SPIR-V at build time into ${LFGI_SPIRV_DIR}/<name>.spv. glslc writes a depfile, so an
# edited header under shaders/shared/ rebuilds every shader that includes it.
function(lfgi_add_shaders target)
  cmake_parse_arguments(ARG "" "" "SOURCES" ${ARGN})
  set(outputs)
  foreach(src ${ARG_SOURCES})
    get_filename_component(name ${src} NAME_WE)
    set(abs ${CMAKE_CURRENT_SOURCE_DIR}/${src})
    set(out ${LFGI_SPIRV_DIR}/${name}.spv)
    set(dep ${CMAKE_CURRENT_BINARY_DIR}/${name}.spv.d)
    add_custom_command(
      OUTPUT ${out}
      COMMAND ${CMAKE_COMMAND} -E make_directory ${LFGI_SPIRV_DIR}
      COMMAND ${GLSLC} --target-env=vulkan1.3 -O -Werror -I ${CMAKE_SOURCE_DIR}/shaders
              -MD -MF ${dep} -MT ${out} -o ${out} ${abs}
      DEPENDS ${abs}
      DEPFILE ${dep}
      COMMENT "glslc ${src}"
      VERBATIM)
    list(APPEND outputs ${out})
  endforeach()
  add_custom_target(${target} ALL DEPENDS ${outputs})
endfunction()
