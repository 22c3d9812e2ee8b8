# One library target per folder, COLMAP-style: sightmap_add_library(NAME core SRCS ... DEPS ...).
# Compiler warnings are on for every target and are errors unless SIGHTMAP_WERROR is OFF.

# No -Wnull-dereference: at -O3 (Release) GCC 12 reports it inside Eigen's and nlohmann-json's
# inlined code, where nothing of ours can be changed, and -Werror then fails the build.
function(sightmap_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
                                           -Wold-style-cast -Wcast-align -Wunused -Woverloaded-virtual
                                           -Wformat=2)
  if(SIGHTMAP_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

# sightmap_add_library(NAME n SRCS a.cc b.cc PUBLIC_DEPS x PRIVATE_DEPS y)
function(sightmap_add_library)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  set(target sightmap_${ARG_NAME})
  add_library(${target} STATIC ${ARG_SRCS})
  target_include_directories(${target} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(${target} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  sightmap_set_warnings(${target})
endfunction()

# sightmap_add_test(NAME n SRCS a_test.cc DEPS x [LABELS l] [TIMEOUT seconds, default 300])
function(sightmap_add_test)
  if(NOT SIGHTMAP_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "NAME;TIMEOUT" "SRCS;DEPS;LABELS" ${ARGN})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  set(target ${ARG_NAME})
  add_executable(${target} ${ARG_SRCS})
  target_link_libraries(${target} PRIVATE ${ARG_DEPS} sightmap_testing GTest::gtest GTest::gtest_main)
  sightmap_set_warnings(${target})
  # A suite's own code is fixtures and assertions (the work is in the libraries, at -O2): -O1 cuts
  # its compile time (after the build type's -O2 on the command line: the later level wins).
  target_compile_options(${target} PRIVATE $<$<CONFIG:RelWithDebInfo>:${SIGHTMAP_TEST_OPT_LEVEL}>)
  # gtest_discover_tests would run every binary at build time; one ctest entry per suite binary keeps
  # the build quick and ctest's summary readable.
  add_test(NAME ${target} COMMAND ${target} --gtest_color=no)
  set_tests_properties(${target} PROPERTIES TIMEOUT ${ARG_TIMEOUT} LABELS "${ARG_LABELS}")
endfunction()
