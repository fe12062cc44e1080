# Flash and RAM of a firmware image against the budget (issue 7: application <= 32 KiB
# flash, <= 6 KiB RAM including the stack, so it fits 8 KiB-RAM parts; goal 16 KiB
# flash), from the linker script's symbols. Also fails if the heap got linked in.
# Prints the figures and writes one row of the size table to OUT.
# Usage: cmake -DNM=arm-none-eabi-nm -DELF=x.elf -DBOARD=arm -DOUT=x.size -P check-budget.cmake
set(BUDGET_FLASH 32768)
set(BUDGET_RAM 6144)
set(GOAL_FLASH 16384)

execute_process(COMMAND ${NM} ${ELF} OUTPUT_VARIABLE syms RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
    message(FATAL_ERROR "nm failed on ${ELF}")
endif()

function(symbol name out)
    if(NOT syms MATCHES "([0-9a-f]+) [A-Za-z] ${name}\n")
        message(FATAL_ERROR "${ELF}: no symbol ${name} (linker script?)")
    endif()
    math(EXPR value "0x${CMAKE_MATCH_1}")
    set(${out} ${value} PARENT_SCOPE)
endfunction()

# No dynamic allocation: nothing may bring in malloc and friends (or sbrk).
string(REGEX MATCHALL "[ \n](malloc|free|calloc|realloc|_malloc_r|_free_r|_sbrk|_sbrk_r)\n"
       heap "${syms}")
if(heap)
    message(FATAL_ERROR "dynamic allocation in ${ELF}: ${heap}")
endif()

symbol(_flash_end flash_end)
symbol(_ram_end ram_end)
symbol(_stack_bottom stack_bottom)
symbol(_sdata sdata)
symbol(_edata edata)
symbol(_sbss sbss)
symbol(_ebss ebss)
math(EXPR flash "${flash_end} - 0x08000000")
math(EXPR ram "${ram_end} - 0x20000000")
math(EXPR stack "${ram_end} - ${stack_bottom}")
math(EXPR data "${edata} - ${sdata}")
math(EXPR bss "${ebss} - ${sbss}")
math(EXPR vectors "${ram} - ${data} - ${bss} - ${stack}") # vector table, alignment
math(EXPR flash_pct "100 * ${flash} / ${BUDGET_FLASH}")
math(EXPR ram_pct "100 * ${ram} / ${BUDGET_RAM}")

set(goal "")
if(flash GREATER GOAL_FLASH)
    set(goal " (over the 16 KiB goal)")
endif()
message(STATUS "servo-${BOARD}: flash ${flash} of ${BUDGET_FLASH} B (${flash_pct}%)${goal}, "
               "RAM ${ram} of ${BUDGET_RAM} B (${ram_pct}%: "
               "vectors ${vectors}, code+data ${data}, bss ${bss}, stack ${stack})")
file(WRITE ${OUT} "${BOARD} ${flash} ${ram} ${vectors} ${data} ${bss} ${stack}\n")
if(flash GREATER BUDGET_FLASH)
    message(FATAL_ERROR "servo-${BOARD}: flash ${flash} B over the ${BUDGET_FLASH} B budget")
endif()
if(ram GREATER BUDGET_RAM)
    message(FATAL_ERROR "servo-${BOARD}: RAM ${ram} B over the ${BUDGET_RAM} B budget")
endif()
