# Obtain Unity (ThrowTheSwitch) at configure time; it is never committed. In order:
#  1. FETCHCONTENT_SOURCE_DIR_UNITY (the standard FetchContent override) or MAGCAL_UNITY_DIR:
#     a Unity source tree given by the caller (any release from 2.4 on).
#  2. ${PROJECT_SOURCE_DIR}/.deps/unity, prepared earlier by tools/get_unity.sh.
#  3. The pinned upstream release below, downloaded and checked against its SHA256.
#  4. tools/get_unity.sh, which takes Unity 2.4.3 from Debian's cjson source package
#     (tests/unity/) through a private apt state, for machines that reach only Debian's archive.
# See docs/decisions/0001-obtaining-unity.md.
set(MAGCAL_UNITY_URL "https://github.com/ThrowTheSwitch/Unity/archive/refs/tags/v2.6.0.tar.gz")
set(MAGCAL_UNITY_SHA256 "aa4c9fb1ae5fc5242f914c65f3557e817e40cb37f04a31e5ff76d1ab89dbf674")
set(MAGCAL_UNITY_DIR "" CACHE PATH "Unity source tree to use instead of downloading one")

set(_unity_dir "")
if(FETCHCONTENT_SOURCE_DIR_UNITY)
    set(_unity_dir "${FETCHCONTENT_SOURCE_DIR_UNITY}")
elseif(MAGCAL_UNITY_DIR)
    set(_unity_dir "${MAGCAL_UNITY_DIR}")
elseif(EXISTS "${PROJECT_SOURCE_DIR}/.deps/unity/src/unity.c")
    set(_unity_dir "${PROJECT_SOURCE_DIR}/.deps/unity")
endif()

if(NOT _unity_dir)
    set(_dl_dir "${PROJECT_BINARY_DIR}/_deps")
    set(_tarball "${_dl_dir}/unity-v2.6.0.tar.gz")
    if(NOT EXISTS "${_dl_dir}/unity-src/src/unity.c")
        message(STATUS "Unity: downloading pinned release ${MAGCAL_UNITY_URL}")
        # The hash is checked by hand: EXPECTED_HASH turns an unreachable network into a hard
        # error, and we want to fall back to Debian's archive instead.
        file(DOWNLOAD "${MAGCAL_UNITY_URL}" "${_tarball}"
             TIMEOUT 60 INACTIVITY_TIMEOUT 15 STATUS _dl_status)
        list(GET _dl_status 0 _dl_code)
        if(_dl_code EQUAL 0)
            file(SHA256 "${_tarball}" _dl_hash)
            if(NOT _dl_hash STREQUAL MAGCAL_UNITY_SHA256)
                file(REMOVE "${_tarball}")
                message(FATAL_ERROR "Unity tarball SHA256 mismatch: got ${_dl_hash}, pinned ${MAGCAL_UNITY_SHA256}")
            endif()
            file(ARCHIVE_EXTRACT INPUT "${_tarball}" DESTINATION "${_dl_dir}/unity-extract")
            file(GLOB _extracted LIST_DIRECTORIES true "${_dl_dir}/unity-extract/*")
            file(REMOVE_RECURSE "${_dl_dir}/unity-src")
            file(RENAME "${_extracted}" "${_dl_dir}/unity-src")
        else()
            file(REMOVE "${_tarball}")
            message(STATUS "Unity: download failed (${_dl_status}); trying Debian's cjson source package")
            execute_process(COMMAND bash "${PROJECT_SOURCE_DIR}/tools/get_unity.sh" "${_dl_dir}/unity-src"
                            RESULT_VARIABLE _gu_rc)
            if(NOT _gu_rc EQUAL 0)
                message(FATAL_ERROR "Unity could not be obtained. Point FETCHCONTENT_SOURCE_DIR_UNITY "
                                    "at a Unity source tree, or run tools/get_unity.sh on a machine with "
                                    "Debian's archive reachable.")
            endif()
        endif()
    endif()
    set(_unity_dir "${_dl_dir}/unity-src")
endif()

if(NOT EXISTS "${_unity_dir}/src/unity.c")
    message(FATAL_ERROR "Unity source tree '${_unity_dir}' has no src/unity.c")
endif()
message(STATUS "Unity: using ${_unity_dir}")
set(MAGCAL_UNITY_SOURCE_DIR "${_unity_dir}" CACHE INTERNAL "")

add_library(unity STATIC "${_unity_dir}/src/unity.c")
target_include_directories(unity SYSTEM PUBLIC "${_unity_dir}/src")
# Test code asserts on doubles (references computed in double); enable Unity's double support.
# Defined empty: Debian's Unity 2.4.3 tree also defines it (empty) in examples/unity_config.h.
target_compile_definitions(unity PUBLIC UNITY_INCLUDE_DOUBLE= UNITY_SUPPORT_64)
set_target_properties(unity PROPERTIES C_STANDARD 99 C_EXTENSIONS OFF)
