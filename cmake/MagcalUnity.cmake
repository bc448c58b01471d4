# Obtain Unity (ThrowTheSwitch) at configure time; it is never committed. One deterministic
# choice, whatever the network does (docs/decisions/0001-obtaining-unity.md):
#  1. a tree the caller names: FETCHCONTENT_SOURCE_DIR_UNITY (the standard FetchContent
#     override) or MAGCAL_UNITY_DIR (any release from 2.4 on);
#  2. ${PROJECT_SOURCE_DIR}/.deps/unity, prepared earlier by tools/get_unity.sh (Debian's 2.4.3);
#  3. default: Unity 2.4.3 from Debian's cjson source package (tests/unity/), unpacked into the
#     build tree by cmake/MagcalDebianCjson.cmake (Debian's archive only, no root);
#  3'. opt-in, -DMAGCAL_UNITY_UPSTREAM=ON: the pinned upstream release v2.6.0 (URL + SHA256);
#     a download failure is an error, never a silent switch to another version.
# The configure output names the version and the origin that was used.
include(${CMAKE_CURRENT_LIST_DIR}/MagcalDebianCjson.cmake)
option(MAGCAL_UNITY_UPSTREAM "Download the pinned upstream Unity v2.6.0 instead of Debian's 2.4.3" OFF)
set(MAGCAL_UNITY_URL "https://github.com/ThrowTheSwitch/Unity/archive/refs/tags/v2.6.0.tar.gz")
set(MAGCAL_UNITY_SHA256 "aa4c9fb1ae5fc5242f914c65f3557e817e40cb37f04a31e5ff76d1ab89dbf674")
set(MAGCAL_UNITY_DIR "" CACHE PATH "Unity source tree to use instead of obtaining one")

set(_unity_dir "")
set(_unity_origin "")
if(FETCHCONTENT_SOURCE_DIR_UNITY)
    set(_unity_dir "${FETCHCONTENT_SOURCE_DIR_UNITY}")
    set(_unity_origin "FETCHCONTENT_SOURCE_DIR_UNITY")
elseif(MAGCAL_UNITY_DIR)
    set(_unity_dir "${MAGCAL_UNITY_DIR}")
    set(_unity_origin "MAGCAL_UNITY_DIR")
elseif(EXISTS "${PROJECT_SOURCE_DIR}/.deps/unity/src/unity.c")
    set(_unity_dir "${PROJECT_SOURCE_DIR}/.deps/unity")
    set(_unity_origin ".deps/unity (tools/get_unity.sh)")
elseif(MAGCAL_UNITY_UPSTREAM)
    set(_dl_dir "${PROJECT_BINARY_DIR}/_deps")
    set(_tarball "${_dl_dir}/unity-v2.6.0.tar.gz")
    set(_unity_dir "${_dl_dir}/unity-upstream-src")
    set(_unity_origin "pinned upstream release ${MAGCAL_UNITY_URL} (MAGCAL_UNITY_UPSTREAM=ON)")
    if(NOT EXISTS "${_unity_dir}/src/unity.c")
        file(DOWNLOAD "${MAGCAL_UNITY_URL}" "${_tarball}" EXPECTED_HASH SHA256=${MAGCAL_UNITY_SHA256}
             TIMEOUT 60 INACTIVITY_TIMEOUT 15 STATUS _dl_status)
        list(GET _dl_status 0 _dl_code)
        if(NOT _dl_code EQUAL 0)
            file(REMOVE "${_tarball}")
            message(FATAL_ERROR "MAGCAL_UNITY_UPSTREAM=ON: download of ${MAGCAL_UNITY_URL} failed "
                                "(${_dl_status}). Configure without it to use Debian's Unity 2.4.3.")
        endif()
        file(ARCHIVE_EXTRACT INPUT "${_tarball}" DESTINATION "${_dl_dir}/unity-extract")
        file(GLOB _extracted LIST_DIRECTORIES true "${_dl_dir}/unity-extract/*")
        file(REMOVE_RECURSE "${_unity_dir}")
        file(RENAME "${_extracted}" "${_unity_dir}")
    endif()
else()
    magcal_debian_cjson_dir(_cjson_dir "Unity 2.4.3 for the tests")
    magcal_debian_cjson_version("${_cjson_dir}" _cjson_ver)
    set(_unity_dir "${_cjson_dir}/tests/unity")
    set(_unity_origin "Debian's cjson ${_cjson_ver} source package")
endif()

if(NOT EXISTS "${_unity_dir}/src/unity.c")
    message(FATAL_ERROR "Unity source tree '${_unity_dir}' has no src/unity.c")
endif()
set(_unity_ver "?")
if(EXISTS "${_unity_dir}/release/version.info")
    file(STRINGS "${_unity_dir}/release/version.info" _unity_ver LIMIT_COUNT 1)
endif()
message(STATUS "Unity ${_unity_ver}: ${_unity_origin} (${_unity_dir})")
set(MAGCAL_UNITY_SOURCE_DIR "${_unity_dir}" CACHE INTERNAL "")
set(MAGCAL_UNITY_VERSION "${_unity_ver}" CACHE INTERNAL "")

add_library(unity STATIC "${_unity_dir}/src/unity.c")
target_include_directories(unity SYSTEM PUBLIC "${_unity_dir}/src")
# Test code asserts on doubles (references computed in double); enable Unity's double support.
# Defined empty: Debian's Unity 2.4.3 tree also defines it (empty) in examples/unity_config.h.
target_compile_definitions(unity PUBLIC UNITY_INCLUDE_DOUBLE= UNITY_SUPPORT_64)
set_target_properties(unity PROPERTIES C_STANDARD 99 C_EXTENSIONS OFF)
