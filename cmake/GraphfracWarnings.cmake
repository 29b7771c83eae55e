# Project code builds with warnings as errors; third-party headers come in as SYSTEM.
function(gf_project_target target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Werror)
endfunction()

# Sanitizers for the asan preset (GF_SANITIZE=ON).
option(GF_SANITIZE "Build with AddressSanitizer and UndefinedBehaviorSanitizer" OFF)
if(GF_SANITIZE)
  # C++ only: nvcc does not take these flags (the CUDA objects are compile-only here anyway).
  add_compile_options(
    "$<$<COMPILE_LANGUAGE:CXX>:-fsanitize=address,undefined;-fno-omit-frame-pointer;-fno-sanitize-recover=all>")
  add_link_options(-fsanitize=address,undefined)
endif()
