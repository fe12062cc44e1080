/* bench_store.c - `make bench` figures of the persistent store: flash used, worst-case
 * flash operations of one write and of boot recovery, and ten years of one EEPROM write
 * per second against the STM32F1's 10,000 erase cycles per page. */
#include <stdio.h>
#include <string.h>

#include "hal_host.h"
#include "store.h"

static struct hal hal;
static struct regs r;
static struct store st;

static void boot(uint32_t now)
{
    hal_host_reboot(&hal);
    regs_init(&r, &board_foot);
    hal.flash.ops = 0;
    store_load(&st, &hal, &r, now);
}

int main(void)
{
    printf("== persistent store (EEPROM registers on flash)\n");
    printf("flash used: %u pages x %u bytes = %u bytes; %u record slots per page\n",
           HAL_FLASH_PAGES, HAL_FLASH_PAGE_BYTES, HAL_FLASH_PAGES * HAL_FLASH_PAGE_BYTES,
           (unsigned)STORE_SLOTS);

    /* Worst case of one write: every EEPROM register changes at once, at every fill level
     * of the page, with and without the pre-erase having run. */
    hal_host_init(&hal);
    boot(0);
    st.refill_us = 0;
    uint32_t worst_sync = 0, worst_poll = 0, worst_boot = 0;
    for (uint32_t i = 0; i < 3000u; i++) {
        if (i % 7u == 0u) { /* everything at once */
            r.mem[REG_ID] = (uint8_t)(i % 250u);
            r.mem[REG_RETURN_DELAY] = (uint8_t)i;
            regs_set(&r, REG_CW_LIMIT, (uint16_t)(i % 50u));
            regs_set(&r, REG_CCW_LIMIT, (uint16_t)(60u + i % 50u));
            r.mem[REG_TEMPERATURE_LIMIT] = (uint8_t)(i + 1u);
            r.mem[REG_CURRENT_LIMIT] = (uint8_t)(i + 2u);
            r.mem[REG_RESOLUTION] = (uint8_t)(1u + i % 200u);
            r.mem[REG_STATUS_RETURN_LEVEL] = (uint8_t)(i % 3u);
            r.mem[REG_HEARTBEAT_ENABLE] = (uint8_t)(i % 2u);
            r.mem[REG_UNLOAD_CONDITIONS] = (uint8_t)(i % 128u);
            r.mem[REG_HOMING_ZERO_SIDE] = (uint8_t)(1u + i % 2u);
            r.mem[REG_RS485_TERMINATION] = (uint8_t)(i % 2u);
            r.mem[REG_BAUD_RATE] = (uint8_t)(i % 11u);
        } else {
            r.mem[REG_RETURN_DELAY] = (uint8_t)i;
        }
        hal.flash.ops = 0;
        store_sync(&st, &r, 0);
        worst_sync = hal.flash.ops > worst_sync ? hal.flash.ops : worst_sync;
        hal.flash.ops = 0;
        if (i % 3u) /* sometimes the motor is busy and no pre-erase runs */
            store_poll(&st, &r, 0, true);
        worst_poll = hal.flash.ops > worst_poll ? hal.flash.ops : worst_poll;
        if (i % 97u == 0u) {
            uint8_t keep[REGS_SIZE];
            memcpy(keep, r.mem, sizeof keep);
            boot(0);
            st.refill_us = 0;
            worst_boot = hal.flash.ops > worst_boot ? hal.flash.ops : worst_boot;
            if (memcmp(keep, r.mem, sizeof keep) != 0) {
                printf("FAIL: a reboot lost a value\n");
                return 1;
            }
        }
    }
    printf("worst-case flash operations of one host write: %u (programs, plus one erase only "
           "if the idle-time pre-erase has not run); of the idle-time pre-erase: %u erase; of "
           "boot recovery: %u (it only reads)\n", worst_sync, worst_poll, worst_boot);

    /* Ten years, the host writing one EEPROM register once a second (a new value each
     * time), the store's rate limit in force, the motor idle now and then. */
    hal_host_init(&hal);
    boot(0);
    const uint32_t seconds = 10u * 365u * 24u * 3600u;
    uint32_t now = 0;
    uint64_t elapsed_us = 0;
    for (uint32_t s = 0; s < seconds; s++) {
        r.mem[REG_RETURN_DELAY] = (uint8_t)s;
        store_sync(&st, &r, now);
        store_poll(&st, &r, now, (s & 15u) == 0u);
        now += 1000000u; /* wraps every 71 minutes, like the MCU's clock */
        elapsed_us += 1000000u;
    }
    uint32_t max_erases = 0;
    printf("endurance, 10 years x 1 write/s (%u writes), erases per page:", seconds);
    for (uint8_t p = 0; p < HAL_FLASH_PAGES; p++) {
        printf(" %u", hal.flash.erases[p]);
        max_erases = hal.flash.erases[p] > max_erases ? hal.flash.erases[p] : max_erases;
    }
    printf("\n  worst page %u of 10,000 rated cycles (%.0f%%); %llu s simulated\n", max_erases,
           100.0 * max_erases / 10000.0, (unsigned long long)(elapsed_us / 1000000u));
    return max_erases <= 10000u ? 0 : 1;
}
