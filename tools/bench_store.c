/* bench_store.c - `make bench` figures of the persistent store: flash records written by
 * 10,000 packets of mixed bus traffic next to the EEPROM values they changed, flash used,
 * worst-case flash operations of one write and of boot recovery, and ten years of one
 * EEPROM write per second against the STM32F1's 10,000 erase cycles per page. */
#include <stdio.h>
#include <string.h>

#include "hal_host.h"
#include "proto.h"
#include "store.h"
#include "vbus.h"

static struct hal hal;
static struct regs r;
static struct store st;

static const struct board *board = &board_foot;

static void boot(uint32_t now)
{
    hal_host_reboot(&hal);
    regs_init(&r, board);
    hal.flash.ops = 0;
    store_load(&st, &hal, &r, now);
}

static struct vbus bus;
static uint32_t rng = 0x1234567u;
static uint32_t rnd(uint32_t n)
{
    rng ^= rng << 13;
    rng ^= rng >> 17;
    rng ^= rng << 5;
    return rng % n;
}

static bool stored(const struct board *b, uint8_t a)
{
    return regs_applicable(b, a) && regs_table[a].area == REG_AREA_EE &&
           (regs_table[a].access & REG_ACCESS_W);
}

/* 10,000 packets of mixed traffic on the bus of an arm (ID 1), with the commit budget in
 * force: READs and PINGs, RAM writes, EEPROM writes of new and of unchanged values,
 * packets for other IDs, SYNC WRITE. Every flash record must be one changed value. */
static int traffic(void)
{
    vbus_init(&bus);
    bus.host_baud = board_arm.default_baud;
    bus.step_us = 100;
    vbus_add(&bus, &board_arm, 0);
    struct servo *s = &bus.node[0].servo;
    struct hal *h = &bus.node[0].hal;
    uint32_t quiet_packets = 0, quiet_programs = 0, changing = 0, values = 0, appended = 0;
    uint32_t compactions = 0, compaction_records = 0, compacted_values = 0, deferred = 0;
    for (uint32_t i = 0; i < 10000u; i++) {
        uint8_t before[REGS_SIZE], d[8], pkt[32], id = 1, ins = INS_WRITE, n = 2;
        memcpy(before, s->regs.mem, sizeof before);
        uint32_t k = rnd(1000);
        d[0] = REG_TEMPERATURE_LIMIT;
        d[1] = before[REG_TEMPERATURE_LIMIT];
        if (k < 6) { /* 0.6 %: a new EEPROM value (temperature limit, or a CCW limit
                      * whose high byte changes: the case of issue 19) */
            if (rnd(2)) {
                d[1] = (uint8_t)(60u + rnd(30));
            } else {
                uint16_t v = (uint16_t)(200u + rnd(2) * 100u + rnd(50));
                d[0] = REG_CCW_LIMIT;
                d[1] = (uint8_t)v;
                d[2] = (uint8_t)(v >> 8);
                n = 3;
            }
        } else if (k < 100) { /* the same EEPROM value again */
        } else if (k < 400) {
            ins = INS_READ;
            d[0] = REG_TURNED_ANGLE;
            d[1] = 2;
        } else if (k < 550) {
            ins = INS_PING;
            n = 0;
        } else if (k < 700) { /* RAM */
            d[0] = REG_BRAKE;
            d[1] = (uint8_t)rnd(2);
        } else if (k < 850) { /* another servo's business: also a new EEPROM value */
            id = (uint8_t)(2u + rnd(10));
            d[1] = (uint8_t)(60u + rnd(30));
        } else { /* SYNC WRITE of the temperature limit to another ID */
            id = PROTO_ID_BROADCAST;
            ins = INS_SYNC_WRITE;
            d[0] = REG_TEMPERATURE_LIMIT;
            d[1] = 1;
            d[2] = (uint8_t)(2u + rnd(10));
            d[3] = (uint8_t)(60u + rnd(30));
            n = 4;
        }
        uint16_t len = proto_build_packet(pkt, id, ins, d, n);
        uint32_t programs = h->flash.programs, seq = s->store.seq;
        vbus_host_send(&bus, pkt, len);
        vbus_run_until(&bus, bus.now_us + 30000u);
        while (vbus_host_pending(&bus))
            (void)vbus_host_next(&bus);
        uint32_t changed = 0;
        for (uint8_t a = 0; a < REGS_SIZE; a++)
            changed += stored(&board_arm, a) &&
                       memcmp(&before[a], &s->regs.mem[a], regs_table[a].size) != 0;
        uint32_t wrote = h->flash.programs - programs;
        if (!changed) {
            quiet_packets++;
            quiet_programs += wrote;
            continue;
        }
        changing++;
        values += changed;
        deferred += s->store.pending;
        if (s->store.seq != seq) { /* a compaction: header + commit mark + the image */
            compactions++;
            compaction_records += (wrote - 6u) / 3u;
            compacted_values += changed;
        } else {
            appended += wrote / 3u;
        }
    }
    printf("10,000 packets of mixed traffic to an arm (ID 1) and other IDs, %u s of bus time:\n",
           bus.now_us / 1000000u);
    printf("  %u packets changed no EEPROM value: %u flash records\n", quiet_packets,
           quiet_programs / 3u);
    printf("  %u packets changed %u EEPROM values: %u flash records appended + %u written "
           "by a compaction%s", changing, values, appended, compacted_values,
           appended + compacted_values == values ? " (equal)\n" : " (NOT equal)\n");
    printf("  (compactions: %u; each moves the whole image from a full page to the next one: "
           "%u records with the unchanged values)\n", compactions, compaction_records);
    if (deferred)
        printf("  %u commits deferred by the budget (64, then one per 64 s)\n", deferred);
    return quiet_programs == 0u && deferred == 0u && appended + compacted_values == values ? 0 : 1;
}

/* Worst case of one write on board b: every EEPROM register changes at once, at every
 * fill level of the page, with and without the pre-erase having run. Returns 0, or 1 if a
 * reboot lost a value; the worst counts of flash operations in *sync, *poll, *boot_ops. */
static int worst_write(const struct board *b, uint32_t *sync, uint32_t *poll, uint32_t *boot_ops)
{
    board = b;
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
                printf("FAIL: a reboot lost a value (%s)\n", b->name);
                return 1;
            }
        }
    }
    *sync = worst_sync;
    *poll = worst_poll;
    *boot_ops = worst_boot;
    return 0;
}

int main(void)
{
    printf("== persistent store (EEPROM registers on flash)\n");
    int fail = traffic();
    printf("flash used: %u pages x %u bytes = %u bytes; %u record slots per page\n",
           HAL_FLASH_PAGES, HAL_FLASH_PAGE_BYTES, HAL_FLASH_PAGES * HAL_FLASH_PAGE_BYTES,
           (unsigned)STORE_SLOTS);

    /* A compaction programs 6 header half-words and 3 per register the board keeps. */
    uint32_t worst_sync = 0, worst_poll = 0, worst_boot = 0;
    printf("worst-case flash operations of one host write (programs, plus one erase only if "
           "the idle-time pre-erase has not run), per board:");
    for (uint32_t i = 0; i < BOARD_COUNT; i++) {
        uint32_t sync, poll, boot_ops;
        if (worst_write(board_all[i], &sync, &poll, &boot_ops))
            return 1;
        printf(" %s %u", board_all[i]->name, sync);
        worst_sync = sync > worst_sync ? sync : worst_sync;
        worst_poll = poll > worst_poll ? poll : worst_poll;
        worst_boot = boot_ops > worst_boot ? boot_ops : worst_boot;
    }
    printf("\n  at most %u; of the idle-time pre-erase: %u erase; of boot recovery: %u (it "
           "only reads)\n", worst_sync, worst_poll, worst_boot);

    /* Ten years, the host writing one EEPROM register once a second (a new value each
     * time), the store's rate limit in force, the motor idle now and then. */
    board = &board_foot;
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
    return max_erases <= 10000u && !fail ? 0 : 1;
}
