# Fail if the linked image contains a soft-float or software-divide-of-floats helper:
# the Cortex-M3 has no FPU and the firmware is fixed-point by rule.
execute_process(COMMAND ${NM} ${ELF} OUTPUT_VARIABLE syms RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
    message(FATAL_ERROR "nm failed on ${ELF}")
endif()
string(REGEX MATCHALL "__aeabi_[fd][a-z0-9]+|__(add|sub|mul|div|float|fix)[sd]f[a-z0-9]*" hits "${syms}")
if(hits)
    list(REMOVE_DUPLICATES hits)
    message(FATAL_ERROR "floating point in ${ELF}: ${hits}")
endif()
message(STATUS "no floating point in ${ELF}")
