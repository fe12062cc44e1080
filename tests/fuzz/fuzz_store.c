/* fuzz_store.c - the persistent store (include/store.h) from arbitrary flash contents and
 * power cuts at arbitrary points: recovery at boot, and the writes that follow.
 *
 * Input: byte 0 picks the board; then operations, one byte o each, with their operands
 * (missing bytes read as 0); the store's pages start erased:
 *   o % 8 = 0  WRITE a v0 v1: a host write of register a % 50 (its 1 or 2 bytes from v0 v1;
 *              ignored unless the table would take it, regs_write_valid), then store_sync
 *           1  CUT k: the power goes at the (k & 31) + 1-th next program or erase, kind
 *              (k >> 5) % 3 (clean, done, torn); the servo then boots again
 *           2  BOOT: power cycle, recovery
 *           3  POKE p o0 o1 v: byte (o0 | o1 << 8) % 1024 of store page p % 4 := v
 *           4  HALF p o v0 v1: the half-word there := v0 | v1 << 8
 *           5  FILL p v: every byte of store page p % 4 := v
 *           6  TIME t: (t + 1) s pass, then store_poll (motor idle if t is even)
 *           7  FLUSH: store_flush (the servo is about to restart)
 * At most MAX_OPS operations; then a last boot.
 *
 * Invariants (abort on violation), at every boot:
 *   1. it boots a valid table: every register the store keeps within its range, CW <=
 *      CCW (regs_first_invalid), every other register (identity included) at its factory
 *      value; and update mode (loader_settings) listens with the ID, baud and return delay
 *      the table holds;
 *   2. it never touches a page outside the store: no erase or program reaches one (the
 *      flash's per-page counts, after every operation);
 *   3. a second recovery of its own result changes nothing: booting again from the same
 *      flash gives the same table and store state, and syncing the recovered table
 *      writes nothing. */
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "fuzz.h"
#include "hal_host.h"
#include "loader.h"
#include "regs.h"
#include "store.h"

#define MAX_OPS 96u

const char fuzz_target_name[] = "fuzz_store";

static struct hal hal;
static struct store st;
static struct regs table;
static const struct board *board;

/* Invariant 2, cheaply after every operation: no erase or program outside the store. */
static void check_outside_writes(void)
{
    for (unsigned p = HAL_FLASH_PAGES; p < FLASH_SIM_PAGES; p++)
        FUZZ_CHECK(hal.flash.writes[p] == 0u);
}

/* Per board, made once: its factory table (regs_init's result), and the bytes of the
 * registers the store does not keep (a mask over the table's bytes). */
static struct {
    bool made;
    struct regs table;
    uint8_t fixed[REGS_SIZE]; /* 0xFF: a byte the store must leave at its factory value */
} factory[BOARD_COUNT];
static unsigned board_no;

static void factory_make(void)
{
    if (factory[board_no].made)
        return;
    regs_init(&factory[board_no].table, board);
    for (uint8_t a = 0; a < REGS_SIZE; a++) {
        uint8_t size = regs_table[a].size;
        bool kept = regs_applicable(board, a) && regs_table[a].area == REG_AREA_EE &&
                    (regs_table[a].access & REG_ACCESS_W);
        for (uint8_t i = 0; !kept && i < size; i++)
            factory[board_no].fixed[a + i] = 0xFFu;
    }
    factory[board_no].made = true;
}

/* Power comes back and the servo boots: recovery into a factory table, checked. */
FUZZ_NO_COVERAGE static void boot(uint32_t now)
{
    flash_sim_power_on(&hal.flash);
    const struct regs *fresh = &factory[board_no].table;
    table = *fresh; /* what regs_init() gives */
    store_load(&st, &hal, &table, now);

    /* 1: a valid table. */
    FUZZ_CHECK(regs_first_invalid(&table) == REGS_SIZE);
    for (uint8_t a = 0; a < REGS_SIZE; a++)
        FUZZ_CHECK(((table.mem[a] ^ fresh->mem[a]) & factory[board_no].fixed[a]) == 0u);
    struct loader_settings ls;
    loader_settings(&hal, board, &ls);
    FUZZ_CHECK(ls.id == table.mem[REG_ID]);
    FUZZ_CHECK(ls.baud_code == table.mem[REG_BAUD_RATE]);
    FUZZ_CHECK(ls.delay == table.mem[REG_RETURN_DELAY]);

    /* 3: recovering again changes nothing; writing back what was recovered writes
     * nothing. */
    struct regs again = *fresh;
    struct store st2;
    store_load(&st2, &hal, &again, now);
    FUZZ_CHECK(memcmp(again.mem, table.mem, sizeof table.mem) == 0);
    FUZZ_CHECK(memcmp(&st2, &st, sizeof st) == 0);
    uint32_t ops = hal.flash.ops;
    store_sync(&st2, &again, now);
    FUZZ_CHECK(hal.flash.ops == ops);
    check_outside_writes();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static bool made;
    fuzz_progress();
    if (size < 1u)
        return 0;
    if (!made) {
        hal_host_init(&hal);
        made = true;
    }
    /* A fresh flash: only the store's pages ever change (invariant 2 checks it). */
    for (uint8_t p = 0; p < HAL_FLASH_PAGES; p++)
        memset(hal.flash.mem[p], 0xFF, HAL_FLASH_PAGE_BYTES);
    memset(hal.flash.erases, 0, sizeof hal.flash.erases);
    memset(hal.flash.writes, 0, sizeof hal.flash.writes);
    hal.flash.cut_at = 0;
    hal.flash.rng = 0x2545F491u;
    board_no = data[0] % BOARD_COUNT;
    board = board_all[board_no];
    factory_make();
    struct fuzz_reader r = {data + 1, size - 1u};
    uint32_t now = 0;
    boot(now);

    for (unsigned n = 0; r.left && n < MAX_OPS; n++) {
        uint8_t o = fuzz_get8(&r);
        switch (o % 8u) {
        case 0: {
            uint8_t a = fuzz_get8(&r) % REGS_SIZE, v[2];
            v[0] = fuzz_get8(&r);
            v[1] = fuzz_get8(&r);
            uint8_t width = regs_table[a].size;
            if (width && regs_write_valid(&table, a, v, width)) {
                regs_set(&table, a, regs_value(v, width));
                store_sync(&st, &table, now);
            }
            break;
        }
        case 1: {
            uint8_t k = fuzz_get8(&r);
            hal.flash.cut_at = hal.flash.ops + (k & 31u) + 1u;
            hal.flash.cut_kind = (uint8_t)((k >> 5) % 3u);
            break;
        }
        case 2:
            boot(now);
            break;
        case 3: {
            uint8_t p = fuzz_get8(&r) % HAL_FLASH_PAGES;
            uint16_t lo = fuzz_get8(&r);
            uint16_t off = (uint16_t)((lo | (uint16_t)(fuzz_get8(&r) << 8)) % HAL_FLASH_PAGE_BYTES);
            hal.flash.mem[p][off] = fuzz_get8(&r);
            break;
        }
        case 4: {
            uint8_t p = fuzz_get8(&r) % HAL_FLASH_PAGES;
            uint16_t off = (uint16_t)(2u * (fuzz_get8(&r) % (HAL_FLASH_PAGE_BYTES / 2u)));
            hal.flash.mem[p][off] = fuzz_get8(&r);
            hal.flash.mem[p][off + 1u] = fuzz_get8(&r);
            break;
        }
        case 5: {
            uint8_t p = fuzz_get8(&r) % HAL_FLASH_PAGES;
            memset(hal.flash.mem[p], fuzz_get8(&r), HAL_FLASH_PAGE_BYTES);
            break;
        }
        case 6: {
            uint8_t t = fuzz_get8(&r);
            now += (t + 1u) * 1000000u;
            store_poll(&st, &table, now, (t & 1u) == 0u);
            break;
        }
        default:
            store_flush(&st, &table, now);
            break;
        }
        if (!hal.flash.powered) /* the cut happened: the servo boots again */
            boot(now);
        check_outside_writes();
    }
    hal.flash.cut_at = 0;
    boot(now);
    return 0;
}
