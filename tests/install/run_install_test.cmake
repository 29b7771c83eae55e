# Runs as `cmake -P` from the install.find_package test (see CMakeLists.txt beside it).
# Inputs: GF_BUILD_DIR GF_WORK_DIR GF_CONSUMER_DIR GF_CONFIG GF_GENERATOR GF_CXX_COMPILER
#         GF_EXTRA_FLAGS GF_PREFIX_PATH ('|'-separated) GF_EXPECT_BULLET (ON/OFF).
cmake_minimum_required(VERSION 3.25)

set(prefix ${GF_WORK_DIR}/prefix)
set(consumer_build ${GF_WORK_DIR}/consumer)
# Start clean so a stale install or consumer cache cannot make the test pass.
file(REMOVE_RECURSE ${GF_WORK_DIR})

set(config_args "")
if(GF_CONFIG)
  set(config_args --config ${GF_CONFIG})
endif()

function(step what)
  message(STATUS "install test: ${what}")
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "install test: ${what} failed (${rc})")
  endif()
endfunction()

step("cmake --install into ${prefix}"
     ${CMAKE_COMMAND} --install ${GF_BUILD_DIR} --prefix ${prefix} ${config_args})

string(REPLACE "|" ";" prefix_path "${GF_PREFIX_PATH}")
list(PREPEND prefix_path ${prefix})
string(REPLACE ";" "\\;" prefix_path_arg "${prefix_path}")
set(build_type_arg "")
if(GF_CONFIG)
  set(build_type_arg -DCMAKE_BUILD_TYPE=${GF_CONFIG})
endif()
step("configure the consumer"
     ${CMAKE_COMMAND} -S ${GF_CONSUMER_DIR} -B ${consumer_build} -G ${GF_GENERATOR}
     -DCMAKE_CXX_COMPILER=${GF_CXX_COMPILER} ${build_type_arg}
     "-DCMAKE_PREFIX_PATH=${prefix_path_arg}"
     "-DCMAKE_CXX_FLAGS=${GF_EXTRA_FLAGS}" "-DCMAKE_EXE_LINKER_FLAGS=${GF_EXTRA_FLAGS}"
     -DGF_REQUIRE_BULLET=${GF_EXPECT_BULLET}
     # Only the fresh prefix may satisfy find_package(graphfrac), never a copy elsewhere.
     -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF -DCMAKE_FIND_USE_SYSTEM_PACKAGE_REGISTRY=OFF)

# find_package must have resolved to the prefix we just installed.
file(STRINGS ${consumer_build}/CMakeCache.txt found_dir REGEX "^graphfrac_DIR:")
string(REGEX REPLACE "^[^=]*=" "" found_dir "${found_dir}")
cmake_path(IS_PREFIX prefix "${found_dir}" NORMALIZE in_prefix)
if(NOT in_prefix)
  message(FATAL_ERROR "install test: graphfrac_DIR is '${found_dir}', not under ${prefix}")
endif()

step("build the consumer" ${CMAKE_COMMAND} --build ${consumer_build} ${config_args})

find_program(consumer_exe graphfrac_consumer PATHS ${consumer_build} ${consumer_build}/${GF_CONFIG}
             NO_DEFAULT_PATH REQUIRED)
# The consumer checks its own physics; also insist on its closing line so that a run that
# exits 0 early (or prints nothing) cannot pass.
message(STATUS "install test: run ${consumer_exe}")
execute_process(COMMAND ${consumer_exe} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
message("${out}")
if(NOT rc EQUAL 0 OR NOT out MATCHES "graphfrac consumer: ok")
  message(FATAL_ERROR "install test: the consumer failed (exit ${rc})")
endif()

# The Bullet component, when this build has it.
if(GF_EXPECT_BULLET)
  find_program(bullet_exe graphfrac_consumer_bullet PATHS ${consumer_build}
               ${consumer_build}/${GF_CONFIG} NO_DEFAULT_PATH REQUIRED)
  message(STATUS "install test: run ${bullet_exe}")
  execute_process(COMMAND ${bullet_exe} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
  message("${out}")
  if(NOT rc EQUAL 0 OR NOT out MATCHES "graphfrac bullet consumer: ok")
    message(FATAL_ERROR "install test: the Bullet consumer failed (exit ${rc})")
  endif()
endif()
