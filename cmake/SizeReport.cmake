# cmake -P SizeReport.cmake with SIZE, NM, LIB, OUT: writes arm-none-eabi-size per object and a
# total, and fails if any software double-precision helper is referenced (the library is float32).
execute_process(COMMAND ${SIZE} -t ${LIB} OUTPUT_VARIABLE size_out RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
    message(FATAL_ERROR "size failed on ${LIB}")
endif()
execute_process(COMMAND ${NM} -u ${LIB} OUTPUT_VARIABLE nm_out)
string(REGEX MATCHALL "__aeabi_(d[a-z0-9]+|f2d|i2d|ui2d|l2d|ul2d)" dbl "${nm_out}")
list(REMOVE_DUPLICATES dbl)
file(WRITE ${OUT} "${size_out}\nsoftware double helpers referenced: ${dbl}\n")
message(STATUS "libmagcal.a size report:\n${size_out}")
if(dbl)
    message(FATAL_ERROR "double-precision soft-float helpers referenced by libmagcal.a: ${dbl}")
endif()
