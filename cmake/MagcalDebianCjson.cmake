# Debian's `cjson` source package, unpacked once per build tree at configure time (never
# committed). It is the one outside source the build may need: Unity 2.4.3 for the tests
# (tests/unity/) and the cJSON library for the replay harness where libcjson-dev is absent.
# tools/get_debian_cjson.sh fetches it through a private apt state from Debian's archive only.
#   magcal_debian_cjson_dir(<out_var> <why>)  -> path of the unpacked tree (FATAL_ERROR if it
#                                                cannot be had: nothing is silently skipped)
# MAGCAL_CJSON_SOURCE_DIR names an existing tree instead (e.g. prepared before going offline).
include_guard(GLOBAL)
set(MAGCAL_CJSON_SOURCE_DIR "" CACHE PATH
    "Unpacked Debian cjson source tree (cJSON.c, tests/unity/); empty: fetched into the build tree")

function(magcal_debian_cjson_dir out_var why)
    if(MAGCAL_CJSON_SOURCE_DIR)
        set(_dir "${MAGCAL_CJSON_SOURCE_DIR}")
    else()
        set(_dir "${CMAKE_BINARY_DIR}/_deps/cjson-src")
        if(NOT EXISTS "${_dir}/cJSON.c" OR NOT EXISTS "${_dir}/tests/unity/src/unity.c")
            message(STATUS "Fetching Debian's cjson source package (${why})")
            execute_process(COMMAND bash "${PROJECT_SOURCE_DIR}/tools/get_debian_cjson.sh" "${_dir}"
                            RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _err
                            OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_STRIP_TRAILING_WHITESPACE)
            if(NOT _rc EQUAL 0)
                message(FATAL_ERROR "Debian's cjson source package could not be obtained (${why}):\n"
                    "${_err}\nFix one of: make Debian's archive reachable; install libcjson-dev "
                    "(replay harness); set MAGCAL_CJSON_SOURCE_DIR to an unpacked tree "
                    "(tools/get_debian_cjson.sh DIR on another machine); FETCHCONTENT_SOURCE_DIR_UNITY "
                    "to a Unity tree; or configure with -DBUILD_TESTING=OFF -DMAGCAL_BUILD_TOOLS=OFF.")
            endif()
        endif()
    endif()
    if(NOT EXISTS "${_dir}/cJSON.c" OR NOT EXISTS "${_dir}/tests/unity/src/unity.c")
        message(FATAL_ERROR "'${_dir}' is not an unpacked cjson source tree (no cJSON.c or tests/unity)")
    endif()
    set(${out_var} "${_dir}" PARENT_SCOPE)
endfunction()

# Version of the tree (Debian version when fetched by the script, else from cJSON.h).
function(magcal_debian_cjson_version dir out_var)
    if(EXISTS "${dir}/.debian_version")
        file(STRINGS "${dir}/.debian_version" _v LIMIT_COUNT 1)
    else()
        file(STRINGS "${dir}/cJSON.h" _l REGEX "#define CJSON_VERSION_(MAJOR|MINOR|PATCH)")
        string(REGEX REPLACE "[^0-9;]" "" _v "${_l}")
        string(REPLACE ";" "." _v "${_v}")
    endif()
    set(${out_var} "${_v}" PARENT_SCOPE)
endfunction()
