# Stand-in for CMake's CTest module during a cross build with MAGCAL_TARGET_TESTS=ON (put first
# on CMAKE_MODULE_PATH by cmake/target/MagcalTargetHook.cmake): run the real module, then add
# Unity and tests/ so the portable tests are built for and run on QEMU mps2-an386.
include(${CMAKE_ROOT}/Modules/CTest.cmake)
if(BUILD_TESTING AND NOT TARGET unity)
    include(${PROJECT_SOURCE_DIR}/cmake/MagcalUnity.cmake)
    add_subdirectory(${PROJECT_SOURCE_DIR}/tests ${PROJECT_BINARY_DIR}/tests)
endif()
