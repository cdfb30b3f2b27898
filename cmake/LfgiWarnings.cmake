# lfgi_warnings: every lfgi target links this INTERFACE target.
add_library(lfgi_warnings INTERFACE)
target_compile_options(lfgi_warnings INTERFACE -Wall -Wextra -Wpedantic -Wshadow -Wconversion-null
                                                -Wnon-virtual-dtor -Wimplicit-fallthrough)
if(LFGI_WERROR)
  target_compile_options(lfgi_warnings INTERFACE -Werror)
endif()
