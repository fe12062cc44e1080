# Fail if a JSON copy the host SDK keeps (tools/python/servobus/registers.json from
# src/regs.c, protocol.json from src/dispatch.c and include/proto.h) is not exactly what
# `regdoc FLAG` generates. FLAG defaults to --json.
if(NOT FLAG)
    set(FLAG --json)
endif()
execute_process(COMMAND ${REGDOC} ${FLAG} OUTPUT_VARIABLE generated RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
    message(FATAL_ERROR "regdoc ${FLAG} failed")
endif()
file(READ ${JSON} checked_in)
if(NOT generated STREQUAL checked_in)
    message(FATAL_ERROR "${JSON} is out of date with the firmware's tables: run "
                        "`make docs` (build/host/tools/regdoc ${FLAG} > ${JSON})")
endif()
message(STATUS "${JSON} matches the firmware's tables")
