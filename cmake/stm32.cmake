# Cross build for the STM32F103: the firmware image of one board (BOARD, board/<name>/)
# on the port in hal/stm32f1/. Floating point is banned from the core and the port:
# -mgeneral-regs-only makes any float arithmetic a compile error, and the link checks
# below fail the build if a soft-float helper, the heap, or flash-resident code on the
# interrupt path sneaks into the image, or if it outgrows its flash and RAM budget.
set(SERVO_BOARDS base foot arm wrist finger)
if(NOT BOARD IN_LIST SERVO_BOARDS)
    message(FATAL_ERROR "BOARD=${BOARD}: choose one of ${SERVO_BOARDS}")
endif()
include(${CMAKE_SOURCE_DIR}/board/${BOARD}/board.cmake) # BOARD_MCU
set(SERVO_LDSCRIPT ${CMAKE_SOURCE_DIR}/board/${BOARD_MCU}.ld)

# -fstack-usage: each function's frame (.su beside its object) for stack_report.py.
foreach(part bus motion)
    target_compile_options(servo_${part} PRIVATE -mgeneral-regs-only -fstack-usage)
endforeach()

find_program(SERVO_PYTHON3 python3 PATHS /usr/bin NO_DEFAULT_PATH)
find_program(SERVO_PYTHON3 python3 REQUIRED)

set(image servo-${BOARD})
add_executable(${image}.elf
    hal/stm32f1/startup.c
    hal/stm32f1/clock.c
    hal/stm32f1/gpio.c
    hal/stm32f1/uart.c
    hal/stm32f1/flash.c
    hal/stm32f1/motor.c
    hal/stm32f1/iwdg.c
    hal/stm32f1/main.c)
target_include_directories(${image}.elf PRIVATE hal/stm32f1 board/${BOARD})
target_link_libraries(${image}.elf PRIVATE servo_core)
target_compile_options(${image}.elf PRIVATE ${SERVO_WARNINGS} -mgeneral-regs-only -fstack-usage)
target_compile_definitions(${image}.elf PRIVATE SERVO_BOARD=board_${BOARD})
target_link_options(${image}.elf PRIVATE
    -T${SERVO_LDSCRIPT}
    -Wl,-Map=${CMAKE_BINARY_DIR}/${image}.map)
# Relink (and so re-run the checks below) when the linker script or a check changes.
set(checks hal/stm32f1/check_isr_ram.py hal/stm32f1/stack_report.py
    cmake/check-budget.cmake cmake/check-no-float.cmake)
list(TRANSFORM checks PREPEND ${CMAKE_SOURCE_DIR}/)
set_target_properties(${image}.elf PROPERTIES LINK_DEPENDS "${SERVO_LDSCRIPT};${checks}")

add_custom_command(TARGET ${image}.elf POST_BUILD
    COMMAND ${CMAKE_COMMAND} -DNM=arm-none-eabi-nm -DELF=$<TARGET_FILE:${image}.elf>
            -P ${CMAKE_SOURCE_DIR}/cmake/check-no-float.cmake
    COMMAND ${SERVO_PYTHON3} ${CMAKE_SOURCE_DIR}/hal/stm32f1/check_isr_ram.py
            $<TARGET_FILE:${image}.elf>
    COMMAND ${SERVO_PYTHON3} ${CMAKE_SOURCE_DIR}/hal/stm32f1/stack_report.py
            $<TARGET_FILE:${image}.elf> ${CMAKE_BINARY_DIR} ${CMAKE_BINARY_DIR}/${image}.stack
    COMMAND ${CMAKE_COMMAND} -DNM=arm-none-eabi-nm -DELF=$<TARGET_FILE:${image}.elf>
            -DBOARD=${BOARD} -DOUT=${CMAKE_BINARY_DIR}/${image}.size
            -P ${CMAKE_SOURCE_DIR}/cmake/check-budget.cmake
    COMMAND ${CMAKE_OBJCOPY} -O binary $<TARGET_FILE:${image}.elf> ${CMAKE_BINARY_DIR}/${image}.bin
    COMMAND ${CMAKE_OBJCOPY} -O ihex $<TARGET_FILE:${image}.elf> ${CMAKE_BINARY_DIR}/${image}.hex
    BYPRODUCTS ${CMAKE_BINARY_DIR}/${image}.bin ${CMAKE_BINARY_DIR}/${image}.hex
               ${CMAKE_BINARY_DIR}/${image}.map ${CMAKE_BINARY_DIR}/${image}.size
               ${CMAKE_BINARY_DIR}/${image}.stack
    VERBATIM)

# The porting checklist compiles against hal.h (signatures kept in step); never linked.
add_library(hal_template OBJECT hal/template/hal_template.c)
target_include_directories(hal_template PRIVATE hal)
target_compile_options(hal_template PRIVATE ${SERVO_WARNINGS} -mgeneral-regs-only)
