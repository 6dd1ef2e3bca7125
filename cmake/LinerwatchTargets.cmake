# Helpers shared by every component. Keep them small; anything component-specific belongs in the
# component's own CMakeLists.txt.

# Warnings are errors on project code (never on third-party headers: those come in as SYSTEM).
function(lw_project_warnings target)
  target_compile_options(${target} PRIVATE
    -Wall -Wextra -Wpedantic -Werror -Wshadow -Wnon-virtual-dtor -Wcast-align
    -Wunused -Wnull-dereference -Wdouble-promotion -Wformat=2 -Wimplicit-fallthrough)
endfunction()

# Freestanding code (protocol, firmware, the MCU HAL ports): no exceptions, no RTTI, no thread-safe
# statics, and on the MCU no unwinding tables. The same flags apply on the host so host tests catch
# violations. Implicit conversions that may change a value or its sign are errors here too
# (-Wconversion -Wsign-conversion with lw_project_warnings' -Werror): on the wire and in the
# firmware's fixed-width fields a silent truncation is a corrupted reading.
function(lw_freestanding target)
  target_compile_options(${target} PRIVATE
    $<$<COMPILE_LANGUAGE:CXX>:-fno-exceptions -fno-rtti -fno-threadsafe-statics>
    -ffunction-sections -fdata-sections -Wconversion -Wsign-conversion)
  if(LW_BARE_METAL)
    target_compile_options(${target} PRIVATE -ffreestanding -fno-unwind-tables -fno-asynchronous-unwind-tables)
  endif()
  lw_project_warnings(${target})
endfunction()

# Prints the size of a freestanding static library after it is built (cross builds only).
function(lw_print_size target)
  if(LW_BARE_METAL AND CMAKE_SIZE)
    add_custom_command(TARGET ${target} POST_BUILD
      COMMAND ${CMAKE_SIZE} --totals $<TARGET_FILE:${target}>
      COMMENT "Size of ${target} (arm-none-eabi)")
  endif()
endfunction()

# One CppUTest binary per module, registered with ctest.
#   lw_add_unit_test(NAME test_x SOURCES a.cpp b.cpp LIBS lib1 lib2 [LABELS l] [TIMEOUT s])
function(lw_add_unit_test)
  cmake_parse_arguments(T "" "NAME;TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${T_NAME} ${T_SOURCES} ${PROJECT_SOURCE_DIR}/tests/support/cpputest_main.cpp)
  target_link_libraries(${T_NAME} PRIVATE ${T_LIBS} PkgConfig::CPPUTEST)
  target_include_directories(${T_NAME} PRIVATE ${PROJECT_SOURCE_DIR}/tests)
  set_target_properties(${T_NAME} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/tests)
  lw_project_warnings(${T_NAME})
  add_test(NAME ${T_NAME} COMMAND ${T_NAME} -c)
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 120)
  endif()
  set_tests_properties(${T_NAME} PROPERTIES TIMEOUT ${T_TIMEOUT})
  if(T_LABELS)
    set_tests_properties(${T_NAME} PROPERTIES LABELS "${T_LABELS}")
  endif()
endfunction()

# A test that cannot run on this machine is still registered, and reported by ctest as skipped
# (exit 77) with the reason in its output, instead of silently missing from the list.
#   lw_add_skipped_test(NAME test_x REASON "mosquitto not found (scripts/install-deps installs it)" [LABELS l])
function(lw_add_skipped_test)
  cmake_parse_arguments(T "" "NAME;REASON" "LABELS" ${ARGN})
  add_test(NAME ${T_NAME} COMMAND sh -c "echo skipped: $1; exit 77" sh "${T_REASON}")
  set_tests_properties(${T_NAME} PROPERTIES SKIP_RETURN_CODE 77)
  if(T_LABELS)
    set_tests_properties(${T_NAME} PROPERTIES LABELS "${T_LABELS}")
  endif()
endfunction()

# An integration test against real programs and a real mosquitto on 127.0.0.1 (tests/support/
# mosquitto_fixture). Each program target P becomes a build dependency and a compile definition
# LW_<P without "linerwatch-", upper case>_BIN (linerwatch-server -> LW_SERVER_BIN); the broker
# binary reaches the test as $LW_MOSQUITTO. Without mosquitto it is reported as skipped (ctest).
#   lw_add_integration_test(NAME test_x SOURCES a.cpp LIBS l1 l2 PROGRAMS linerwatch-server [TIMEOUT s])
function(lw_add_integration_test)
  cmake_parse_arguments(T "" "NAME;TIMEOUT" "SOURCES;LIBS;PROGRAMS" ${ARGN})
  foreach(program ${T_PROGRAMS})
    if(NOT TARGET ${program})
      return()
    endif()
  endforeach()
  find_program(LW_MOSQUITTO mosquitto PATHS /usr/sbin /usr/local/sbin)
  if(NOT LW_MOSQUITTO)
    message(WARNING "mosquitto not found: ${T_NAME} is not built (scripts/install-deps)")
    lw_add_skipped_test(NAME ${T_NAME} REASON "mosquitto not found (scripts/install-deps installs it)" LABELS integration)
    return()
  endif()
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 300)
  endif()
  lw_add_unit_test(NAME ${T_NAME}
    SOURCES ${T_SOURCES} ${PROJECT_SOURCE_DIR}/tests/support/mosquitto_fixture.cpp
    LIBS ${T_LIBS} Threads::Threads LABELS integration TIMEOUT ${T_TIMEOUT})
  foreach(program ${T_PROGRAMS})
    string(REPLACE "linerwatch-" "" short ${program})
    string(TOUPPER ${short} short)
    target_compile_definitions(${T_NAME} PRIVATE LW_${short}_BIN="$<TARGET_FILE:${program}>")
    add_dependencies(${T_NAME} ${program})
  endforeach()
  # mosquitto lives in /usr/sbin, which is not on every user's PATH (MosquittoFixture reads this).
  set_tests_properties(${T_NAME} PROPERTIES ENVIRONMENT "LW_MOSQUITTO=${LW_MOSQUITTO}")
endfunction()
