# cmake -DNM=<nm> -DLIB=<libmagcal_switches_off.a> -P check_symbols.cmake
# Fails when a function of a disabled feature is defined in the archive, or when one of the 2-D
# pipeline's is missing (the check would then prove nothing).
execute_process(COMMAND ${NM} -g --defined-only ${LIB} OUTPUT_VARIABLE _syms RESULT_VARIABLE _rc)
if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "${NM} failed on ${LIB}")
endif()
set(_absent
    magcal_dbscan_run                                          # DBSCAN
    magcal_errmodel_fit magcal_errmodel_eval magcal_ellipse_kphi # PAPER
    magcal_ellipsoid_fit magcal_ellipsoid_calibrate magcal_ellipsoid_apply
    magcal_optics_run3 magcal_optics_filter3 magcal_optics_auto_params3 # 3D
    magcal_geomag_eval magcal_geomag_wmm2025 magcal_geomag_igrf14 magcal_geomag_schmidt_a # GEOMAG
    magcal_aided_init_checked magcal_aided_update               # AIDED
    magcal_swing_fit magcal_swing_cog_add                       # SWING
    magcal_coarse_bound magcal_coarse_radius magcal_ph_co_fit)  # COARSE
set(_present magcal_optics_filter magcal_consensus_run magcal_ellipse_fit magcal_ellipse_to_cal
             magcal_heading_compute magcal_calibrator_run)
set(_bad "")
foreach(s ${_absent})
    if(_syms MATCHES "[ \t]${s}\n")
        list(APPEND _bad "${s} (defined, its feature is off)")
    endif()
endforeach()
foreach(s ${_present})
    if(NOT _syms MATCHES "[ \t]${s}\n")
        list(APPEND _bad "${s} (missing)")
    endif()
endforeach()
if(_bad)
    message(FATAL_ERROR "libmagcal with every MAGCAL_CFG_ENABLE_* = 0: ${_bad}")
endif()
message(STATUS "every disabled feature's functions absent, the 2-D pipeline present")
