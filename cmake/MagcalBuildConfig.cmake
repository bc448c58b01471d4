# Record the configuration libmagcal.a is built with in a generated header,
# ${PROJECT_BINARY_DIR}/include/magcal/config_build.h, installed with the package. magcal/config.h
# includes it when MAGCAL_PACKAGE_CONFIG is defined (the installed CMake target and magcal.pc
# define it), so a find_package / pkg-config consumer sees the library's values, and a consumer
# that overrides one of the integer limits with another value fails to compile with a message
# naming it (the run-time fingerprint check of the inits is the second line of defence).
# The values are read from the compiler itself (-E -dM over config.h with the library's flags),
# so -D flags, MAGCAL_CONFIG_DEFINES and a MAGCAL_USER_CONFIG header are all seen.
set(MAGCAL_CONFIG_DEFINES "" CACHE STRING
    "Configuration macros for the library build, e.g. MAGCAL_COVERAGE_BINS=72;MAGCAL_MAX_SAMPLES=512")

set(_cfg_int MAGCAL_MAX_SAMPLES MAGCAL_MAX_MIN_PTS MAGCAL_GRID_MAX_CELLS MAGCAL_COVERAGE_BINS
             MAGCAL_SWING_COG_BINS MAGCAL_CONSENSUS_MAX_ITER MAGCAL_CONSENSUS_MAX_REFINE
             # feature switches (CMake options MAGCAL_ENABLE_*, MAGCAL_FEATURE_DEFINES): they size
             # nothing, but a consumer must see the declarations the library was built with
             MAGCAL_CFG_ENABLE_DBSCAN MAGCAL_CFG_ENABLE_OPTICS_CLASSIC MAGCAL_CFG_ENABLE_PAPER
             MAGCAL_CFG_ENABLE_3D MAGCAL_CFG_ENABLE_GEOMAG MAGCAL_CFG_ENABLE_AIDED MAGCAL_CFG_ENABLE_SWING
             MAGCAL_CFG_ENABLE_COARSE)
set(_cfg_float MAGCAL_ELLIPSE_PIVOT_TOL MAGCAL_ELLIPSE_PARABOLA_TOL MAGCAL_ELLIPSE_COLLINEAR_TOL
               MAGCAL_HEADING_ZERO_FIELD_FRAC)

string(TOUPPER "${CMAKE_BUILD_TYPE}" _bt)
separate_arguments(_flags UNIX_COMMAND "${CMAKE_C_FLAGS} ${CMAKE_C_FLAGS_${_bt}}")
set(_defs "")
foreach(d ${MAGCAL_CONFIG_DEFINES} ${MAGCAL_FEATURE_DEFINES})
    list(APPEND _defs "-D${d}")
endforeach()
execute_process(
    COMMAND ${CMAKE_C_COMPILER} ${_flags} ${_defs} -std=c99 -E -dM -I${PROJECT_SOURCE_DIR}/include
            ${PROJECT_SOURCE_DIR}/include/magcal/config.h
    RESULT_VARIABLE _rc OUTPUT_VARIABLE _dm ERROR_VARIABLE _err)
if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "magcal: cannot preprocess include/magcal/config.h with the library's flags:\n${_err}")
endif()

function(_magcal_macro_value text name out)
    string(REGEX MATCH "#define ${name} ([^\n]*)" _m "${text}")
    set(${out} "${CMAKE_MATCH_1}" PARENT_SCOPE)
endfunction()

set(MAGCAL_BUILD_CONFIG_BODY "")
foreach(m ${_cfg_int})
    _magcal_macro_value("${_dm}" ${m} _v)
    if(_v STREQUAL "")
        message(FATAL_ERROR "magcal: ${m} not defined by config.h")
    endif()
    set(MAGCAL_BUILD_${m} "${_v}")
    string(APPEND MAGCAL_BUILD_CONFIG_BODY
        "#if defined(${m}) && (${m} != ${_v})\n"
        "#error \"${m}: this translation unit uses another value than the installed libmagcal.a (${_v}); rebuild magcal with it (MAGCAL_CONFIG_DEFINES, README 'Build configuration')\"\n"
        "#endif\n#ifndef ${m}\n#define ${m} ${_v}\n#endif\n")
endforeach()
string(APPEND MAGCAL_BUILD_CONFIG_BODY
    "/* Used inside the library only (not checkable by the preprocessor): the values it was built with. */\n")
foreach(m ${_cfg_float})
    _magcal_macro_value("${_dm}" ${m} _v)
    string(APPEND MAGCAL_BUILD_CONFIG_BODY "#ifndef ${m}\n#define ${m} ${_v}\n#endif\n")
endforeach()

# Float ABI and target of the prebuilt archive (the .a is tied to them: README "Linking").
_magcal_macro_value("${_dm}" __ARM_PCS_VFP _vfp)
_magcal_macro_value("${_dm}" __arm__ _arm)
_magcal_macro_value("${_dm}" __SOFTFP__ _softfp)
if(NOT _arm STREQUAL "")
    if(NOT _vfp STREQUAL "")
        set(MAGCAL_BUILD_FLOAT_ABI "hard")
    elseif(NOT _softfp STREQUAL "")
        set(MAGCAL_BUILD_FLOAT_ABI "soft")
    else()
        set(MAGCAL_BUILD_FLOAT_ABI "softfp")
    endif()
    set(_abi_check
        "#if !defined(__arm__)\n#error \"this libmagcal.a was built for ARM (${CMAKE_SYSTEM_PROCESSOR}, float ABI ${MAGCAL_BUILD_FLOAT_ABI}); install the package built for this target\"\n#endif\n")
    if(MAGCAL_BUILD_FLOAT_ABI STREQUAL "hard")
        string(APPEND _abi_check
            "#if !defined(__ARM_PCS_VFP)\n#error \"libmagcal.a uses the hard-float calling convention (-mfloat-abi=hard); this translation unit does not\"\n#endif\n")
    else()
        string(APPEND _abi_check
            "#if defined(__ARM_PCS_VFP)\n#error \"libmagcal.a uses the ${MAGCAL_BUILD_FLOAT_ABI} float ABI; this translation unit uses -mfloat-abi=hard\"\n#endif\n")
    endif()
else()
    set(MAGCAL_BUILD_FLOAT_ABI "native (${CMAKE_SYSTEM_PROCESSOR})")
    set(_abi_check
        "#if defined(__arm__) && !defined(__linux__)\n#error \"this libmagcal.a was built for the host (${CMAKE_SYSTEM_PROCESSOR}); install the package built for this target (e.g. the cortex-m4f preset)\"\n#endif\n")
endif()
string(APPEND MAGCAL_BUILD_CONFIG_BODY "${_abi_check}")
string(REPLACE ";" " " _flags_str "${_flags} ${_defs}")
string(STRIP "${_flags_str}" _flags_str)
set(MAGCAL_BUILD_TARGET_DESC "${CMAKE_SYSTEM_NAME} ${CMAKE_SYSTEM_PROCESSOR}, ${CMAKE_C_COMPILER_ID} ${CMAKE_C_COMPILER_VERSION}")
string(REPLACE "\"" "'" _flags_str "${_flags_str}")

file(WRITE ${PROJECT_BINARY_DIR}/include/magcal/config_build.h.tmp
"/* Generated by magcal's configure step (cmake/MagcalBuildConfig.cmake): the configuration the
 * installed libmagcal.a was built with. Included by magcal/config.h when MAGCAL_PACKAGE_CONFIG is
 * defined (the installed CMake target magcal::magcal and magcal.pc define it). Do not edit. */
#ifndef MAGCAL_CONFIG_BUILD_H
#define MAGCAL_CONFIG_BUILD_H

#define MAGCAL_BUILD_VERSION \"${PROJECT_VERSION}\"
#define MAGCAL_BUILD_TARGET \"${MAGCAL_BUILD_TARGET_DESC}\"
#define MAGCAL_BUILD_FLOAT_ABI \"${MAGCAL_BUILD_FLOAT_ABI}\"
#define MAGCAL_BUILD_FLAGS \"${_flags_str}\"

${MAGCAL_BUILD_CONFIG_BODY}
#endif /* MAGCAL_CONFIG_BUILD_H */
")
configure_file(${PROJECT_BINARY_DIR}/include/magcal/config_build.h.tmp
               ${PROJECT_BINARY_DIR}/include/magcal/config_build.h COPYONLY)
message(STATUS "magcal: build configuration COVERAGE_BINS=${MAGCAL_BUILD_MAGCAL_COVERAGE_BINS} "
               "MAX_SAMPLES=${MAGCAL_BUILD_MAGCAL_MAX_SAMPLES}, float ABI ${MAGCAL_BUILD_FLOAT_ABI} "
               "(include/magcal/config_build.h)")
