# Flash and RAM of a firmware image against its budget, from the linker script's symbols
# (_flash_start, _flash_end, _ram_end, and the budgets _budget_flash, _budget_ram: the
# application 27 KiB - 4 flash (its slot less the install mark), the bootloader 6 KiB; 6 KiB RAM including the stack for both,
# so they fit 8 KiB-RAM parts). Also fails if the heap got linked in. Prints the figures
# and writes one row of make firmware's size table to OUT:
#   ROW flash ram vectors code+data bss stack flash-budget ram-budget
# Usage: cmake -DNM=arm-none-eabi-nm -DELF=x.elf -DNAME=servo-arm -DROW=arm -DOUT=x.size
#              [-DGOAL_FLASH=16384] [-DTARGET_FLASH=5632] -P check-budget.cmake
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

symbol(_budget_flash budget_flash)
symbol(_budget_ram budget_ram)
symbol(_flash_start flash_start)
symbol(_flash_end flash_end)
symbol(_ram_end ram_end)
symbol(_stack_bottom stack_bottom)
symbol(_sdata sdata)
symbol(_edata edata)
symbol(_sbss sbss)
symbol(_ebss ebss)
math(EXPR flash "${flash_end} - ${flash_start}")
math(EXPR ram "${ram_end} - 0x20000000")
math(EXPR stack "${ram_end} - ${stack_bottom}")
math(EXPR data "${edata} - ${sdata}")
math(EXPR bss "${ebss} - ${sbss}")
math(EXPR vectors "${ram} - ${data} - ${bss} - ${stack}") # vector table, alignment
math(EXPR flash_pct "100 * ${flash} / ${budget_flash}")
math(EXPR ram_pct "100 * ${ram} / ${budget_ram}")

# GOAL_FLASH: a size goal the image has reached: the build fails past it, so it stays
# reached. TARGET_FLASH: one it has not reached yet: only reported.
set(goal "")
if(DEFINED TARGET_FLASH AND flash GREATER TARGET_FLASH)
    set(goal " (over the ${TARGET_FLASH} B target)")
endif()
message(STATUS "${NAME}: flash ${flash} of ${budget_flash} B (${flash_pct}%)${goal}, "
               "RAM ${ram} of ${budget_ram} B (${ram_pct}%: "
               "vectors ${vectors}, code+data ${data}, bss ${bss}, stack ${stack})")
file(WRITE ${OUT} "${ROW} ${flash} ${ram} ${vectors} ${data} ${bss} ${stack} "
                "${budget_flash} ${budget_ram}\n")
if(DEFINED GOAL_FLASH AND flash GREATER GOAL_FLASH)
    message(FATAL_ERROR "${NAME}: flash ${flash} B over the ${GOAL_FLASH} B goal")
endif()
if(flash GREATER budget_flash)
    message(FATAL_ERROR "${NAME}: flash ${flash} B over the ${budget_flash} B budget")
endif()
if(ram GREATER budget_ram)
    message(FATAL_ERROR "${NAME}: RAM ${ram} B over the ${budget_ram} B budget")
endif()
