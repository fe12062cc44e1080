/* demo.c - `make demo-bytes`: a foot, an arm and a base (host-built firmware) on the
 * virtual bus in virtual time, driven through a scripted session of bus transactions;
 * every packet, its timing and what it means is printed. (`make demo` is the real-time
 * session through the Python SDK, tools/demo.py.) */
#include <stdio.h>
#include <string.h>

#include "proto.h"
#include "vbus.h"

static struct vbus bus;

static void print_bytes(const uint8_t *p, uint32_t n)
{
    for (uint32_t i = 0; i < n; i++)
        printf(" %02X", p[i]);
}

static void print_err(uint8_t err)
{
    static const char *const names[8] = {"over-temperature", "over-current", "over-voltage",
                                         "under-voltage", "checksum error",
                                         "instruction error", "stall", "bit 7"};
    if (!err) {
        printf("ok");
        return;
    }
    const char *sep = "";
    for (int b = 0; b < 8; b++)
        if (err & (1u << b)) {
            printf("%s%s", sep, names[b]);
            sep = ", ";
        }
}

/* Send a packet (checksum filled in unless keep_chk), listen for wait_us, print all. */
static void transact(const char *what, uint8_t *pkt, uint32_t n, int keep_chk, uint32_t wait_us)
{
    if (!keep_chk)
        pkt[n - 1u] = proto_sum(&pkt[2], (uint16_t)(n - 3u));
    printf("\n%s\n  host  ->", what);
    print_bytes(pkt, n);
    printf("\n");
    vbus_host_send(&bus, pkt, n);
    vbus_run_until(&bus, bus.now_us + wait_us);
    uint8_t ans[64];
    uint32_t len = 0, start = 0;
    int any = 0;
    while (vbus_host_pending(&bus)) {
        const struct vbus_byte *w = vbus_host_next(&bus);
        if (len == 0)
            start = w->start_us;
        ans[len++] = w->byte;
        if (len >= 4 && len == (uint32_t)ans[3] + 4u) {
            any = 1;
            printf("  ID %-3u <-", ans[2]);
            print_bytes(ans, len);
            printf("   after %u us: ", start - bus.last_host_end_us);
            if (ans[4] == 0x01 && len == 7u) {
                printf("present, ");
                print_err(ans[5]);
            } else {
                print_err(ans[4]);
                if (len > 6u) {
                    printf(", data");
                    print_bytes(&ans[5], len - 6u);
                }
            }
            printf("\n");
            len = 0;
        }
    }
    if (!any)
        printf("  (no answer)\n");
}

static void show_reg(uint8_t node, const char *name, uint8_t addr)
{
    printf("  -> servo ID %u (%s) %s = %u\n", bus.node[node].servo.link.id,
           bus.node[node].servo.board->name, name, regs_get(&bus.node[node].servo.regs, addr));
}

int main(void)
{
    vbus_init(&bus);
    vbus_add(&bus, &board_foot, 1);
    vbus_add(&bus, &board_arm, 2);
    vbus_add(&bus, &board_base, 3);
    /* Put the base on the 9600 baud bus with the others (its factory rate is 115200). */
    bus.node[2].servo.regs.mem[REG_BAUD_RATE] = 2;
    link_latch(&bus.node[2].servo);
    bus.host_baud = 9600;
    printf("Virtual bus at 9600 baud: foot ID 1, arm ID 2, base ID 3 (factory settings,\n"
           "return delay 8 ms for foot and arm, 4 ms for the base).\n");

    uint8_t ping_all[] = {0xD5, 0x5D, 0xFE, 0x02, 0x01, 0};
    transact("1. Broadcast PING: every servo answers in its own ID-ordered slot", ping_all,
             sizeof ping_all, 0, 60000);

    for (uint8_t id = 1; id <= 3; id++) {
        uint8_t rd[] = {0xD5, 0x5D, id, 0x04, 0x02, 0x00, 0x03, 0};
        transact("2. READ model number and firmware version (addresses 0-2)", rd, sizeof rd, 0,
                 30000);
    }

    uint8_t delay0[] = {0xD5, 0x5D, 0x02, 0x04, 0x03, 0x05, 0x00, 0};
    transact("3. WRITE return delay 0 to the arm: answered after the old 8 ms delay", delay0,
             sizeof delay0, 0, 30000);
    uint8_t ping2[] = {0xD5, 0x5D, 0x02, 0x02, 0x01, 0};
    transact("   PING the arm again: now it answers at once", ping2, sizeof ping2, 0, 30000);

    uint8_t reg1[] = {0xD5, 0x5D, 0x01, 0x05, 0x04, 0x1E, 0x5A, 0x00, 0};
    transact("4. REG WRITE goal 90 to the foot (held, not applied)", reg1, sizeof reg1, 0, 30000);
    uint8_t reg2[] = {0xD5, 0x5D, 0x02, 0x05, 0x04, 0x1E, 0xB4, 0x00, 0};
    transact("   REG WRITE goal 180 to the arm", reg2, sizeof reg2, 0, 30000);
    show_reg(0, "registered (44)", REG_REGISTERED);
    uint8_t action[] = {0xD5, 0x5D, 0xFE, 0x02, 0x05, 0};
    transact("   Broadcast ACTION: both apply at the same instant, nobody answers", action,
             sizeof action, 0, 30000);
    show_reg(0, "goal position (30)", REG_GOAL_POSITION);
    show_reg(1, "goal position (30)", REG_GOAL_POSITION);

    uint8_t sync[] = {0xD5, 0x5D, 0xFE, 0x0D, 0x83, 0x20, 0x02,
                      0x01, 0x1E, 0x00, 0x02, 0x3C, 0x00, 0x03, 0x5A, 0x80, 0};
    transact("5. SYNC WRITE moving speed to all three in one packet (no answer)", sync,
             sizeof sync, 0, 30000);
    show_reg(0, "moving speed (32)", REG_MOVING_SPEED);
    show_reg(1, "moving speed (32)", REG_MOVING_SPEED);
    uint16_t v = regs_get(&bus.node[2].servo.regs, REG_MOVING_SPEED);
    printf("  -> servo ID 3 (base) moving speed (32) = %u, %s (bit 15)\n", v & 0x7FFFu,
           v & 0x8000u ? "negative" : "positive");

    uint8_t bad[] = {0xD5, 0x5D, 0x02, 0x04, 0x03, 0x05, 0x10, 0x00};
    transact("6. A packet damaged on the wire (wrong checksum): not executed, reported", bad,
             sizeof bad, 1, 30000);
    uint8_t oor[] = {0xD5, 0x5D, 0x02, 0x04, 0x03, 0x03, 0xFE, 0};
    transact("   WRITE ID 254 (out of range): refused as a whole", oor, sizeof oor, 0, 30000);

    uint8_t setid[] = {0xD5, 0x5D, 0x01, 0x04, 0x03, 0x03, 0x07, 0};
    transact("7. WRITE ID 7 to the foot: the answer still comes from ID 1", setid, sizeof setid,
             0, 30000);
    uint8_t ping7[] = {0xD5, 0x5D, 0x07, 0x02, 0x01, 0};
    transact("   PING ID 7", ping7, sizeof ping7, 0, 30000);

    uint8_t baud[] = {0xD5, 0x5D, 0x02, 0x04, 0x03, 0x04, 0x04, 0};
    transact("8. WRITE baud 115200 to the arm: answered at 9600, then it switches", baud,
             sizeof baud, 0, 30000);
    transact("   PING the arm at 9600: it no longer hears this rate", ping2, sizeof ping2, 0,
             30000);
    bus.host_baud = 115200;
    transact("   PING the arm at 115200", ping2, sizeof ping2, 0, 30000);
    bus.host_baud = 9600;

    uint8_t reset[] = {0xD5, 0x5D, 0x07, 0x02, 0x06, 0};
    transact("9. RESET the foot (ID 7): answered from ID 7, then factory settings", reset,
             sizeof reset, 0, 30000);
    uint8_t ping1[] = {0xD5, 0x5D, 0x01, 0x02, 0x01, 0};
    transact("   PING ID 1", ping1, sizeof ping1, 0, 30000);

    printf("\n%u bytes on the wire in %u ms of virtual time, %u collisions.\n", bus.wire_len,
           bus.now_us / 1000u, bus.collisions);
    return bus.collisions ? 1 : 0;
}
