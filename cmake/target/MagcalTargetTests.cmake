# On-target Unity tests: every portable tests/test_*.c is cross-compiled for the QEMU
# mps2-an386 board (Cortex-M4F) and run under qemu-system-arm with semihosting, one CTest test
# per executable. Included by tests/CMakeLists.txt when cross-compiling with
# MAGCAL_TARGET_TESTS=ON (preset `cortex-m4f-tests`). See docs/reliability.md and
# docs/decisions/0004-on-target-tests-qemu.md.
include_guard(GLOBAL)

include(${CMAKE_CURRENT_LIST_DIR}/MagcalTargetRuntime.cmake)

# out_var <- TRUE when tests/<src> can run on the target. Excluded: test_shared_* (read
# ../shared files), *replay* (load CSV files), test_mock_* (CMock is host-only), and any test
# whose source contains the marker comment `magcal:host-only`.
function(magcal_target_test_supported src out_var)
    get_filename_component(name ${src} NAME_WE)
    set(ok TRUE)
    if(name MATCHES "^test_shared_" OR name MATCHES "replay" OR name MATCHES "^test_mock_")
        set(ok FALSE)
    else()
        file(STRINGS ${src} marker REGEX "magcal:host-only" LIMIT_COUNT 1)
        if(marker)
            set(ok FALSE)
        endif()
    endif()
    set(${out_var} ${ok} PARENT_SCOPE)
endfunction()

# Make executable `name` a target image and register it as CTest test `name` (label `target`).
function(magcal_target_add_test name)
    magcal_target_add_qemu_test(${name})
    if(name MATCHES "^test_xcheck")
        magcal_target_add_xcheck(${name})
    endif()
endfunction()

# Host/target agreement for test_xcheck*: build the same program for the host with the host C
# compiler (same sources, -O2 like the host preset) and register `<name>_host_vs_target`, which
# runs both and compares their `XCHECK name value` lines (tools/target/xcheck_compare.py).
find_program(MAGCAL_HOST_CC NAMES cc gcc clang)
function(magcal_target_add_xcheck name)
    if(NOT MAGCAL_HOST_CC)
        message(WARNING "no host C compiler: ${name}_host_vs_target not registered")
        return()
    endif()
    get_target_property(_support magcal_test_support SOURCES)
    file(GLOB _lib CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/src/*.c ${PROJECT_SOURCE_DIR}/src/adopt/*.c ${PROJECT_SOURCE_DIR}/src/heading/*.c ${PROJECT_SOURCE_DIR}/src/intake/calibrator_poll*.c ${PROJECT_SOURCE_DIR}/src/filter/*.c
        ${PROJECT_SOURCE_DIR}/src/fit/*.c)
    set(_srcs ${CMAKE_CURRENT_SOURCE_DIR}/${name}.c ${_lib} ${_support}
        ${PROJECT_SOURCE_DIR}/port/fake/magcal_port_fake.c ${MAGCAL_UNITY_SOURCE_DIR}/src/unity.c)
    set(_out ${CMAKE_CURRENT_BINARY_DIR}/${name}_host)
    add_custom_command(OUTPUT ${_out}
        COMMAND ${MAGCAL_HOST_CC} -std=c99 -O2 -DUNITY_INCLUDE_DOUBLE -DUNITY_SUPPORT_64
                -DMAGCAL_SHARED_DIR="${MAGCAL_SHARED_DIR}" -DMAGCAL_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
                -I${PROJECT_SOURCE_DIR}/include -I${PROJECT_SOURCE_DIR}/src -I${PROJECT_SOURCE_DIR}/port
                -I${PROJECT_SOURCE_DIR}/port/fake -I${CMAKE_CURRENT_SOURCE_DIR}/support
                -I${CMAKE_CURRENT_BINARY_DIR}/gen -I${MAGCAL_UNITY_SOURCE_DIR}/src
                ${_srcs} -lm -o ${_out}
        DEPENDS ${_srcs}
        COMMENT "host twin of ${name} for the host/target cross-check" VERBATIM)
    add_custom_target(${name}_host ALL DEPENDS ${_out})
    add_test(NAME ${name}_host_vs_target
             COMMAND ${Python3_EXECUTABLE} ${PROJECT_SOURCE_DIR}/tools/target/xcheck_compare.py
                     --abs-tol 1e-3 --run ${_out} -- ${MAGCAL_TARGET_RUN} $<TARGET_FILE:${name}>)
    set_tests_properties(${name}_host_vs_target PROPERTIES LABELS "target;xcheck" TIMEOUT 300)
endfunction()

# Worst-case stack per library function from this build's .su/.ci files (tools/stack/): fails on
# recursion, dynamic frames, indirect calls, or a public entry point above its budget in
# tools/stack/budgets.txt (default 512 B; larger, documented budgets for the 3-D/model fits).
set(MAGCAL_STACK_BUDGETS ${PROJECT_SOURCE_DIR}/tools/stack/budgets.txt CACHE FILEPATH
    "Per-function worst-case stack budgets (bytes) of the public magcal calls")
add_test(NAME stack_usage
         COMMAND ${Python3_EXECUTABLE} ${PROJECT_SOURCE_DIR}/tools/stack/stack_usage.py
                 ${PROJECT_BINARY_DIR} --budgets ${MAGCAL_STACK_BUDGETS})
set_tests_properties(stack_usage PROPERTIES LABELS "target;stack")

# Validation of the static numbers: tests/target/stack_watermark.c measures the stack the public
# calls really use on the target (painted stack) and the script checks measured <= static.
add_executable(stack_watermark ${PROJECT_SOURCE_DIR}/tests/target/stack_watermark.c)
set_target_properties(stack_watermark PROPERTIES C_STANDARD 99 C_EXTENSIONS OFF SUFFIX ".elf")
target_compile_options(stack_watermark PRIVATE ${MAGCAL_WARNINGS})
target_link_libraries(stack_watermark PRIVATE magcal_test_support magcal_target_rt)
add_test(NAME stack_static_vs_measured
         COMMAND ${Python3_EXECUTABLE} ${PROJECT_SOURCE_DIR}/tools/stack/stack_usage.py
                 ${PROJECT_BINARY_DIR} --ci-dir ${CMAKE_CURRENT_BINARY_DIR}/CMakeFiles/stack_watermark.dir
                 --measured-run ${MAGCAL_TARGET_RUN} $<TARGET_FILE:stack_watermark>)
set_tests_properties(stack_static_vs_measured PROPERTIES LABELS "target;stack")
