# Included right after project(magcal) (CMAKE_PROJECT_magcal_INCLUDE, set by
# cmake/toolchain-cortex-m4f.cmake).
#
# The root CMakeLists.txt adds tests/ only when not cross-compiling, and that file is shared (not
# ours to edit). With MAGCAL_TARGET_TESTS=ON this hook puts cmake/target/ctest_shim first on
# CMAKE_MODULE_PATH, so the root's own `include(CTest)` - which runs after the library and the
# ports are defined - loads the shim: it includes CMake's real CTest module, then Unity and
# tests/ for the target. (cmake_language(DEFER) cannot be used: add_subdirectory is not allowed
# in deferred calls.) Once the root reads
#     if(BUILD_TESTING AND (NOT CMAKE_CROSSCOMPILING OR MAGCAL_TARGET_TESTS))
# the shim steps aside by itself (it looks for MAGCAL_TARGET_TESTS in the root file) and this
# directory's hook and shim can be deleted. See docs/decisions/0004-on-target-tests-qemu.md.
option(MAGCAL_TARGET_TESTS "Cross build: build the Unity tests for QEMU mps2-an386 and run them with CTest" OFF)

if(MAGCAL_TARGET_TESTS AND CMAKE_CROSSCOMPILING)
    file(READ ${PROJECT_SOURCE_DIR}/CMakeLists.txt _magcal_root_text)
    string(FIND "${_magcal_root_text}" "MAGCAL_TARGET_TESTS" _magcal_root_knows)
    if(_magcal_root_knows EQUAL -1)
        list(PREPEND CMAKE_MODULE_PATH ${CMAKE_CURRENT_LIST_DIR}/ctest_shim)
    endif()
    unset(_magcal_root_text)
endif()
