# Cross build for the STM32F103: the core for Cortex-M3 and a link stub image (the real
# port, startup and drivers come with the STM32 issue). Floating point is banned from
# the core: -mgeneral-regs-only makes any float arithmetic a compile error, and the link
# check below fails the build if a soft-float helper sneaks into the image.
foreach(part bus motion)
    target_compile_options(servo_${part} PRIVATE -mgeneral-regs-only)
endforeach()

add_executable(servo-stub.elf hal/stm32f1/stub.c)
target_link_libraries(servo-stub.elf PRIVATE servo_core)
target_compile_options(servo-stub.elf PRIVATE ${SERVO_WARNINGS} -mgeneral-regs-only)
target_compile_definitions(servo-stub.elf PRIVATE SERVO_BOARD=board_${BOARD})
target_link_options(servo-stub.elf PRIVATE
    -T${CMAKE_SOURCE_DIR}/hal/stm32f1/stub.ld
    -Wl,-Map=${CMAKE_BINARY_DIR}/servo-stub.map)
add_custom_command(TARGET servo-stub.elf POST_BUILD
    COMMAND ${CMAKE_COMMAND} -DNM=arm-none-eabi-nm -DELF=$<TARGET_FILE:servo-stub.elf>
            -P ${CMAKE_SOURCE_DIR}/cmake/check-no-float.cmake
    COMMAND ${CMAKE_SIZE} $<TARGET_FILE:servo-stub.elf>
    VERBATIM)
