# Fail if tools/python/servobus/registers.json (the host SDK's copy of the register
# table) is not exactly what `regdoc --json` generates from src/regs.c.
execute_process(COMMAND ${REGDOC} --json OUTPUT_VARIABLE generated RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
    message(FATAL_ERROR "regdoc --json failed")
endif()
file(READ ${JSON} checked_in)
if(NOT generated STREQUAL checked_in)
    message(FATAL_ERROR "${JSON} is out of date with src/regs.c: run "
                        "`build/host/tools/regdoc --json > tools/python/servobus/registers.json`")
endif()
message(STATUS "registers.json matches the table")
