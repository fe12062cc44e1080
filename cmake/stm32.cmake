# Cross build for the STM32F103: the firmware of one board (BOARD, board/<name>/) on the
# port in hal/stm32f1/, as three images in the build directory:
#   servo-<board>.elf/.bin/.hex          the application, linked for the application slot
#                                        (0x08002000); the .bin, stamped by
#                                        tools/fwstamp.py, is the update file (§10)
#   servo-boot-<board>.elf/.bin/.hex     the bootloader (0x08000000, 8 KiB region)
#   servo-<board>-full.bin/.hex          both, for a first flashing (make flash)
# Floating point is banned from the core and the port: -mgeneral-regs-only makes any float
# arithmetic a compile error, and the link checks below fail the build if a soft-float
# helper, the heap, or flash-resident code on the interrupt path sneaks into an image, or
# if it outgrows its flash and RAM budget.
if(NOT BOARD IN_LIST SERVO_BOARDS)
    message(FATAL_ERROR "BOARD=${BOARD}: choose one of ${SERVO_BOARDS}")
endif()
include(${CMAKE_SOURCE_DIR}/board/${BOARD}/board.cmake) # BOARD_MCU
string(TOUPPER ${BOARD} board_upper)
set(SERVO_MODEL BOARD_MODEL_${board_upper}) # include/board.h
set(SERVO_LDDIR ${CMAKE_SOURCE_DIR}/board)
set(SERVO_LDPARTS ${SERVO_LDDIR}/${BOARD_MCU}-memory.ld ${SERVO_LDDIR}/${BOARD_MCU}-sections.ld)
# The flash map of board/stm32f103x8-memory.ld, for the steps after the link.
set(SERVO_BOOT_ORIGIN 0x08000000)
set(SERVO_BOOT_BYTES 8192)
set(SERVO_APP_ORIGIN 0x08002000)
set(SERVO_APP_MAX_BYTES 26620) # image.h IMAGE_MAX_BYTES (image_info.c asserts they agree)

# Passes of -Os that make these images larger, found by building with each one off
# (make firmware's table): jump threading and the dominator optimisations duplicate
# blocks to save branches, loop-invariant motion spills registers it hoisted, tree-level
# tail merging leaves less for the later cross-jumping; in the bootloader also VRP and
# phi-to-conditional rewriting. Then (issue 25, each measured alone and together): the
# second scheduling pass and caller-saves, which the in-order Cortex-M3 gains little from
# and which cost spills; block reordering, loop-invariant motion of tree level,
# if-conversion, partial inlining and forward propagation, which duplicate code
# (about 330 B off the application, 56 B off the bootloader). Then (branch size, each
# measured alone and together, after the struct and table changes): the bootloader's
# phi-to-conditional and straight-line strength reduction off in the application too, and
# sibling-call optimisation off in both, which measured smaller without it (together
# 64 B off the application, 8 B off the bootloader; the worst-case stack grows by 8 B). Only optimisation choices: the code means the same, and the stack and
# ISR-in-RAM checks below still hold it.
set(SERVO_SIZE_OPTIONS_APP -fno-thread-jumps -fno-tree-dominator-opts -fno-move-loop-invariants
    -fno-tree-tail-merge -fno-schedule-insns2 -fno-caller-saves -fno-reorder-blocks
    -fno-tree-loop-im -fno-if-conversion -fno-partial-inlining -fno-forward-propagate -fno-ssa-phiopt
    -fno-tree-slsr -fno-optimize-sibling-calls)
set(SERVO_SIZE_OPTIONS_BOOT -fno-tree-dominator-opts -fno-move-loop-invariants -fno-tree-vrp
    -fno-ssa-phiopt -fno-tree-tail-merge -fno-schedule-insns2 -fno-caller-saves
    -fno-tree-loop-im -fno-if-conversion -fno-forward-propagate -fno-tree-slsr
    -fno-optimize-sibling-calls)

# Link-time optimisation: the core's modules talk through narrow calls, which cost code
# when every call crosses a file; at the link GCC inlines and specialises across them
# (about 1.2 KiB off the application and 0.6 KiB off the bootloader). The code GCC
# generates then comes from the link, so its frame sizes for stack_report.py do too:
# -fstack-usage on the link line, with -dumpdir putting the .su file in the image's own
# directory. Compiled without it: frame_rx.c, whose interrupt functions the linker script
# places in RAM by the name of its object file, and the port's memcpy/memset/memcmp and
# 64-bit division, which GCC calls from the code it generates at the link, after LTO
# would have dropped them as unused.
set(SERVO_LTO -flto)
set_source_files_properties(src/frame_rx.c hal/stm32f1/divmod64.c PROPERTIES
                            COMPILE_OPTIONS -fno-lto)
set_source_files_properties(hal/stm32f1/libc_small.c PROPERTIES
                            COMPILE_OPTIONS "-fno-lto;-fno-tree-loop-distribute-patterns")

# -fstack-usage: each function's frame (.su beside its object) for stack_report.py.
foreach(part bus motion)
    target_compile_options(servo_${part} PRIVATE -mgeneral-regs-only -fstack-usage
                           ${SERVO_LTO} ${SERVO_SIZE_OPTIONS_APP})
endforeach()

find_program(SERVO_PYTHON3 python3 PATHS /usr/bin NO_DEFAULT_PATH)
find_program(SERVO_PYTHON3 python3 REQUIRED)

# The port's files both images use.
set(SERVO_PORT_SOURCES
    hal/stm32f1/startup.c
    hal/stm32f1/clock.c
    hal/stm32f1/gpio.c
    hal/stm32f1/uart.c
    hal/stm32f1/iwdg.c)

# The application's motor, sensors and flash. SERVO_QEMU (CMake preset `qemu`): the arm
# for QEMU's stm32vldiscovery, which models none of them: the arm's plant model in
# integer arithmetic instead of the motor, encoder, ADC and photo switches, and the
# store's pages in RAM instead of the flash controller (hal/stm32f1/README.md). The
# image is then servo-qemu; the bootloader, the rest of the port and the core are the
# arm's.
option(SERVO_QEMU "Build the arm for QEMU's stm32vldiscovery (plant model, RAM flash)" OFF)
if(SERVO_QEMU)
    if(NOT BOARD STREQUAL "arm")
        message(FATAL_ERROR "SERVO_QEMU: the plant model is the arm's (BOARD=arm)")
    endif()
    set(SERVO_IMAGE_NAME qemu)
    set(SERVO_APP_PORT_SOURCES hal/stm32f1/qemu_plant.c hal/stm32f1/qemu_flash.c)
else()
    set(SERVO_IMAGE_NAME ${BOARD})
    set(SERVO_APP_PORT_SOURCES hal/stm32f1/motor.c hal/stm32f1/flash.c hal/stm32f1/uid.c)
endif()

# Relink (and so re-run the checks) when a linker script or a check changes.
set(SERVO_CHECKS hal/stm32f1/check_isr_ram.py hal/stm32f1/stack_report.py
    cmake/check-budget.cmake cmake/check-no-float.cmake)
list(TRANSFORM SERVO_CHECKS PREPEND ${CMAKE_SOURCE_DIR}/)

# Link an image with its linker script, then check it: no float, the interrupt path in
# RAM, the worst-case stack (from the .su files in stack_dirs), the budget (the linker
# script's; writes <name>.size for make firmware's table). Extra arguments: -D options
# for check-budget.cmake.
function(servo_link_and_check name ldscript stack_dirs)
    target_compile_options(${name}.elf PRIVATE ${SERVO_WARNINGS} -mgeneral-regs-only
                           -fstack-usage ${SERVO_LTO})
    target_link_options(${name}.elf PRIVATE
        -L${SERVO_LDDIR} -T${ldscript}
        -Wl,-Map=${CMAKE_BINARY_DIR}/${name}.map
        ${SERVO_LTO} -fstack-usage -dumpdir ${CMAKE_BINARY_DIR}/CMakeFiles/${name}.elf.dir/lto-)
    set_target_properties(${name}.elf PROPERTIES
        LINK_DEPENDS "${ldscript};${SERVO_LDPARTS};${SERVO_CHECKS}")
    list(JOIN stack_dirs ":" dirs)
    add_custom_command(TARGET ${name}.elf POST_BUILD
        COMMAND ${CMAKE_COMMAND} -DNM=arm-none-eabi-nm -DELF=$<TARGET_FILE:${name}.elf>
                -P ${CMAKE_SOURCE_DIR}/cmake/check-no-float.cmake
        COMMAND ${SERVO_PYTHON3} ${CMAKE_SOURCE_DIR}/hal/stm32f1/check_isr_ram.py
                $<TARGET_FILE:${name}.elf>
        COMMAND ${SERVO_PYTHON3} ${CMAKE_SOURCE_DIR}/hal/stm32f1/stack_report.py
                $<TARGET_FILE:${name}.elf> ${dirs} ${CMAKE_BINARY_DIR}/${name}.stack
        COMMAND ${CMAKE_COMMAND} -DNM=arm-none-eabi-nm -DELF=$<TARGET_FILE:${name}.elf>
                -DNAME=${name} -DROW=${SERVO_IMAGE_NAME} -DOUT=${CMAKE_BINARY_DIR}/${name}.size ${ARGN}
                -P ${CMAKE_SOURCE_DIR}/cmake/check-budget.cmake
        BYPRODUCTS ${CMAKE_BINARY_DIR}/${name}.map ${CMAKE_BINARY_DIR}/${name}.size
                   ${CMAKE_BINARY_DIR}/${name}.stack
        VERBATIM)
endfunction()

# ---- The application: the core, the port, main() and the image info block ----
set(image servo-${SERVO_IMAGE_NAME})
add_executable(${image}.elf ${SERVO_PORT_SOURCES} ${SERVO_APP_PORT_SOURCES}
    hal/stm32f1/main.c
    hal/stm32f1/image_info.c
    hal/stm32f1/libc_small.c
    hal/stm32f1/divmod64.c)
target_include_directories(${image}.elf PRIVATE hal/stm32f1 board/${BOARD})
target_compile_options(${image}.elf PRIVATE ${SERVO_SIZE_OPTIONS_APP})
target_link_libraries(${image}.elf PRIVATE servo_core)
# One board per image: the core reads its description as a constant (servo_board()).
foreach(part servo_bus servo_motion)
    target_compile_definitions(${part} PRIVATE SERVO_BOARD_FIXED=board_${BOARD})
endforeach()
target_compile_definitions(${image}.elf PRIVATE SERVO_BOARD=board_${BOARD}
                           SERVO_MODEL=${SERVO_MODEL} SERVO_FW_VERSION=${SERVO_FW_VERSION}
                           SERVO_APP_MAX_BYTES=${SERVO_APP_MAX_BYTES})
servo_link_and_check(${image} ${SERVO_LDDIR}/${BOARD_MCU}.ld
    "${CMAKE_BINARY_DIR}/CMakeFiles/servo_bus.dir;${CMAKE_BINARY_DIR}/CMakeFiles/servo_motion.dir;${CMAKE_BINARY_DIR}/CMakeFiles/${image}.elf.dir"
    -DGOAL_FLASH=16384)
# The update file: the raw binary with its info block completed (length, CRC-32); the
# .hex is that same stamped binary at the application slot's address.
add_custom_command(TARGET ${image}.elf POST_BUILD
    COMMAND ${CMAKE_OBJCOPY} -O binary $<TARGET_FILE:${image}.elf>
            ${CMAKE_BINARY_DIR}/${image}-unstamped.bin
    COMMAND ${SERVO_PYTHON3} ${CMAKE_SOURCE_DIR}/tools/fwstamp.py
            ${CMAKE_BINARY_DIR}/${image}-unstamped.bin ${CMAKE_BINARY_DIR}/${image}.bin
    COMMAND ${CMAKE_OBJCOPY} -I binary -O ihex --change-addresses ${SERVO_APP_ORIGIN}
            ${CMAKE_BINARY_DIR}/${image}.bin ${CMAKE_BINARY_DIR}/${image}.hex
    BYPRODUCTS ${CMAKE_BINARY_DIR}/${image}-unstamped.bin ${CMAKE_BINARY_DIR}/${image}.bin
               ${CMAKE_BINARY_DIR}/${image}.hex
    VERBATIM)

# ---- The bootloader: the port without the motor, and only the core it needs ----
# Compiled here rather than taken from servo_core, so nothing of motion, dispatch or the
# trajectory store can be linked in; servo.c is here for servo_rx_isr() alone (the link's
# garbage collection drops servo_init/servo_poll and what they call).
set(boot servo-boot-${SERVO_IMAGE_NAME})
add_executable(${boot}.elf ${SERVO_PORT_SOURCES}
    hal/stm32f1/flash.c
    hal/stm32f1/boot_main.c
    hal/stm32f1/libc_small.c
    src/frame_rx.c
    src/link.c
    src/proto.c
    src/store.c
    src/crc.c
    src/image.c
    src/boot.c
    src/update.c
    src/loader.c
    src/servo.c
    ${SERVO_BOARD_SOURCES})
target_include_directories(${boot}.elf PRIVATE include hal hal/stm32f1 board/${BOARD})
target_compile_options(${boot}.elf PRIVATE ${SERVO_SIZE_OPTIONS_BOOT})
target_compile_definitions(${boot}.elf PRIVATE SERVO_BOOTLOADER SERVO_BOARD=board_${BOARD}
                           SERVO_BOARD_FIXED=board_${BOARD}
                           SERVO_MODEL=${SERVO_MODEL} SERVO_FW_VERSION=${SERVO_FW_VERSION})
servo_link_and_check(${boot} ${SERVO_LDDIR}/${BOARD_MCU}-boot.ld
    "${CMAKE_BINARY_DIR}/CMakeFiles/${boot}.elf.dir" -DGOAL_FLASH=5632)
add_custom_command(TARGET ${boot}.elf POST_BUILD
    COMMAND ${CMAKE_OBJCOPY} -O binary $<TARGET_FILE:${boot}.elf> ${CMAKE_BINARY_DIR}/${boot}.bin
    COMMAND ${CMAKE_OBJCOPY} -O ihex $<TARGET_FILE:${boot}.elf> ${CMAKE_BINARY_DIR}/${boot}.hex
    BYPRODUCTS ${CMAKE_BINARY_DIR}/${boot}.bin ${CMAKE_BINARY_DIR}/${boot}.hex
    VERBATIM)

# ---- First flashing: the bootloader padded with 0xFF to 8 KiB (the boot record, its
# last KiB, erased), then the stamped application (what make flash writes at 0x08000000,
# and what the QEMU tests boot) ----
set(full ${CMAKE_BINARY_DIR}/${image}-full)
add_custom_command(OUTPUT ${full}.bin ${full}.hex
    COMMAND ${SERVO_PYTHON3} ${CMAKE_SOURCE_DIR}/hal/stm32f1/full_image.py
            ${SERVO_BOOT_BYTES} ${SERVO_APP_MAX_BYTES} ${CMAKE_BINARY_DIR}/${boot}.bin ${CMAKE_BINARY_DIR}/${image}.bin ${full}.bin
    COMMAND ${CMAKE_OBJCOPY} -I binary -O ihex --change-addresses ${SERVO_BOOT_ORIGIN}
            ${full}.bin ${full}.hex
    DEPENDS ${image}.elf ${boot}.elf ${CMAKE_SOURCE_DIR}/hal/stm32f1/full_image.py
    VERBATIM)
add_custom_target(${image}-full ALL DEPENDS ${full}.bin ${full}.hex)

# The porting checklist compiles against hal.h (signatures kept in step); never linked.
add_library(hal_template OBJECT hal/template/hal_template.c)
target_include_directories(hal_template PRIVATE hal)
target_compile_options(hal_template PRIVATE ${SERVO_WARNINGS} -mgeneral-regs-only)
