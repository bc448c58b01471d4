# Optional CMock mocks of the HAL port header (MAGCAL_USE_CMOCK=ON, off by default).
# CMock is never committed: the caller points MAGCAL_CMOCK_DIR at a CMock source tree (the one
# with lib/cmock.rb and src/cmock.c; its vendored Unity submodule is not needed: UNITY_DIR points
# the generator at the Unity tree the tests already use). Mocks are generated into the build tree
# from port/magcal_port.h only. Tests named tests/test_mock_*.c link the mock instead of the fake.
# See docs/decisions/0005-cmock-optional.md.
if(NOT MAGCAL_CMOCK_DIR OR NOT EXISTS "${MAGCAL_CMOCK_DIR}/lib/cmock.rb")
    message(FATAL_ERROR "MAGCAL_USE_CMOCK=ON needs MAGCAL_CMOCK_DIR=<CMock source tree with lib/cmock.rb>")
endif()
find_program(MAGCAL_RUBY ruby REQUIRED)

set(_mock_dir ${CMAKE_CURRENT_BINARY_DIR}/mocks)
set(_mock_cfg ${CMAKE_CURRENT_BINARY_DIR}/cmock.yml)
set(MAGCAL_CMOCK_YML ${_mock_cfg})
# One YAML for the generator (and for any generated runner: they must agree, see style.md).
file(WRITE ${_mock_cfg} ":cmock:\n  :mock_path: ${_mock_dir}\n  :mock_prefix: Mock\n  :plugins:\n    - :ignore\n    - :return_thru_ptr\n    - :expect_any_args\n  :treat_externs: :include\n  :enforce_strict_ordering: true\n  :when_no_prototypes: :warn\n")
add_custom_command(
    OUTPUT ${_mock_dir}/Mockmagcal_port.c ${_mock_dir}/Mockmagcal_port.h
    COMMAND ${CMAKE_COMMAND} -E make_directory ${_mock_dir}
    COMMAND ${CMAKE_COMMAND} -E env UNITY_DIR=${MAGCAL_UNITY_SOURCE_DIR}
            ${MAGCAL_RUBY} ${MAGCAL_CMOCK_DIR}/lib/cmock.rb -o${_mock_cfg} ${PROJECT_SOURCE_DIR}/port/magcal_port.h
    DEPENDS ${PROJECT_SOURCE_DIR}/port/magcal_port.h ${_mock_cfg}
    WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR}
    COMMENT "CMock: generating Mockmagcal_port.{c,h}" VERBATIM)
add_library(magcal_port_mock STATIC ${_mock_dir}/Mockmagcal_port.c ${MAGCAL_CMOCK_DIR}/src/cmock.c)
target_include_directories(magcal_port_mock PUBLIC ${_mock_dir} ${MAGCAL_CMOCK_DIR}/src
                                                   ${PROJECT_SOURCE_DIR}/port)
target_link_libraries(magcal_port_mock PUBLIC magcal unity)
set_target_properties(magcal_port_mock PROPERTIES C_STANDARD 99 C_EXTENSIONS OFF)
