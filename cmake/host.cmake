# Host build: the core with register names compiled in, the host HAL, tests and tools.
option(SERVO_SANITIZE "Build with AddressSanitizer and UndefinedBehaviorSanitizer" ON)
# A Debug build under the sanitizers is compiled at -O1, as ASan's own documentation
# advises: every check stays, and the tests take about a third of the CPU time of -O0
# (issue 28's faster loop: `ctest -L fast` fell from 92 s to 33 s of CPU).
if(SERVO_SANITIZE)
    set(servo_sanitize_flags -fsanitize=address,undefined -fno-sanitize-recover=all
        -fno-omit-frame-pointer $<$<CONFIG:Debug>:-O1>)
    add_compile_options(${servo_sanitize_flags})
    add_link_options(-fsanitize=address,undefined)
    # The core's libraries were created before this file: give them the flags too.
    foreach(part bus motion)
        target_compile_options(servo_${part} PRIVATE ${servo_sanitize_flags})
    endforeach()
endif()

foreach(part bus motion)
    target_compile_definitions(servo_${part} PUBLIC REGS_WITH_TEXT=1)
endforeach()
target_compile_definitions(servo_core PUBLIC REGS_WITH_TEXT=1)

add_library(hal_host STATIC hal/host/hal_host.c hal/host/flash_sim.c hal/host/motor_sim.c)
target_link_libraries(hal_host PUBLIC m)
target_include_directories(hal_host PUBLIC hal hal/host include)
target_compile_options(hal_host PRIVATE ${SERVO_WARNINGS})

# Synthetic application images (hal_host_image_build): the core's CRC-32 stamps them.
add_library(image_host STATIC hal/host/image_host.c hal/host/image_build.c hal/host/power_on.c)
target_link_libraries(image_host PUBLIC servo_core hal_host)
target_compile_options(image_host PRIVATE ${SERVO_WARNINGS})

# One servo on a host bus (power-on, restart, its ID, its output), for both buses.
add_library(node STATIC hal/host/node.c)
target_include_directories(node PUBLIC hal/host)
target_link_libraries(node PUBLIC servo_core hal_host image_host)
target_compile_options(node PRIVATE ${SERVO_WARNINGS})

# The bus line at the bit level (servo-sim's wire; tests/test_wire.c).
add_library(wire STATIC hal/host/wire.c)
target_include_directories(wire PUBLIC hal/host)
target_compile_options(wire PRIVATE ${SERVO_WARNINGS})

# The virtual bus: several host-built servos and a host on one wire, in virtual time.
add_library(vbus STATIC hal/host/vbus.c)
target_include_directories(vbus PUBLIC hal/host)
target_link_libraries(vbus PUBLIC node)
target_compile_options(vbus PRIVATE ${SERVO_WARNINGS})

add_subdirectory(tools)

enable_testing()
add_subdirectory(tests)
