# QEMU mps2-an386 (Cortex-M4F) runtime for on-target tests: start-up object, linker script,
# semihosting exit status, and the QEMU command line. Used by magcal's own suite
# (MagcalTargetTests.cmake) and installed with the package for a consumer's on-target tests:
#   find_package(magcal REQUIRED)
#   include(${magcal_TARGET_DIR}/MagcalTargetRuntime.cmake)
#   add_executable(test_compass test_compass.c)              # main() returns the exit status
#   target_link_libraries(test_compass PRIVATE magcal::magcal my_port)
#   magcal_target_add_qemu_test(test_compass)                 # CTest test, label `target`
# (docs/examples/README.md "On-target tests of your firmware code").
include_guard(GLOBAL)

find_program(MAGCAL_QEMU_ARM qemu-system-arm REQUIRED)
find_program(MAGCAL_TIMEOUT timeout REQUIRED)
set(MAGCAL_TARGET_MACHINE "mps2-an386" CACHE STRING "QEMU machine for the on-target tests")
set(MAGCAL_TARGET_TIMEOUT_S 300 CACHE STRING "Wall-clock limit (s) of one on-target test run (test_optics takes ~30 s alone, >120 s on a loaded 2-core machine)")

set(_tdir ${CMAKE_CURRENT_LIST_DIR})
add_library(magcal_target_rt OBJECT ${_tdir}/startup_mps2_an386.c)
set_target_properties(magcal_target_rt PROPERTIES C_STANDARD 99 C_EXTENSIONS OFF)
if(MAGCAL_WARNINGS)
    target_compile_options(magcal_target_rt PRIVATE ${MAGCAL_WARNINGS})
endif()
# Linking this OBJECT library adds the start-up object; its usage requirements add our linker script, newlib + rdimon
# (semihosting stdio), and the _exit wrapper that reports the real exit status to QEMU.
target_link_options(magcal_target_rt INTERFACE
    -T${_tdir}/mps2_an386.ld -nostartfiles --specs=rdimon.specs -Wl,--wrap=_exit)

# The QEMU command line (toolchain.md): -display none, not -nographic (which exits 1 with stdin
# closed, as in CI); `timeout` turns a hang into a failure.
set(MAGCAL_TARGET_RUN ${MAGCAL_TIMEOUT} ${MAGCAL_TARGET_TIMEOUT_S} ${MAGCAL_QEMU_ARM}
    -M ${MAGCAL_TARGET_MACHINE} -display none -monitor none -serial null
    -semihosting-config enable=on,target=native -kernel)

# Make executable `name` a target image (start-up, linker script, map file, .elf) and register it
# as CTest test `name` run under QEMU (label `target`).
function(magcal_target_add_qemu_test name)
    target_link_libraries(${name} PRIVATE magcal_target_rt)
    target_link_options(${name} PRIVATE -Wl,-Map=$<TARGET_FILE:${name}>.map)
    set_target_properties(${name} PROPERTIES SUFFIX ".elf")
    add_test(NAME ${name} COMMAND ${MAGCAL_TARGET_RUN} $<TARGET_FILE:${name}>)
    set_tests_properties(${name} PROPERTIES LABELS target TIMEOUT 300)
endfunction()
