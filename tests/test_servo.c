/* test_servo.c - a whole servo (receiver, dispatcher, table) under random bus traffic:
 * whatever arrives, the firmware stays inside its buffers (ASan/UBSan), keeps every
 * register in range, never changes a read-only register, answers only well-formed
 * status packets from its own ID, and never answers a broadcast other than PING. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "proto.h"
#include "vbus.h"
#include "test_rng.h"

static uint32_t rng_state = 12345;
static uint32_t rnd(void)
{
    return xorshift32(&rng_state);
}

static struct vbus bus;

/* A random instruction packet to ID 1, broadcast or another ID, mostly well-formed. */
static uint32_t random_packet(uint8_t *out, uint8_t *id_out, uint8_t *ins_out)
{
    static const uint8_t ids[] = {1, 1, 1, PROTO_ID_BROADCAST, 7};
    static const uint8_t inss[] = {INS_PING, INS_READ, INS_WRITE, INS_REG_WRITE, INS_ACTION,
                                   INS_SYNC_WRITE, INS_TRAJ_WRITE, INS_START_END, INS_CUSTOM,
                                   INS_TRAJ_ACTION, 0x09};
    uint8_t id = ids[rnd() % sizeof ids];
    uint8_t ins = inss[rnd() % sizeof inss];
    uint8_t n = (uint8_t)(rnd() % 8u);
    out[0] = PROTO_HEADER0;
    out[1] = PROTO_HEADER1;
    out[2] = id;
    out[3] = (uint8_t)(n + 2u);
    out[4] = ins;
    for (uint8_t i = 0; i < n; i++)
        out[5u + i] = (uint8_t)(i == 0 ? rnd() % 52u : rnd()); /* mostly real addresses */
    out[5u + n] = proto_sum(&out[2], (uint16_t)(n + 3u));
    if (rnd() % 8u == 0u) /* corrupt a byte now and then */
        out[rnd() % (n + 6u)] ^= (uint8_t)(1u << (rnd() % 8u));
    *id_out = id;
    *ins_out = ins;
    return n + 6u;
}

static void assert_table_sane(const struct servo *s, const uint8_t *factory)
{
    for (uint8_t a = 0; a < REGS_SIZE; a++) {
        const struct reg_desc *d = &regs_table[a];
        if (!regs_applicable(s->board, a)) {
            if (!d->size && a && regs_table[a - 1].size == 2)
                continue;
            assert_int_equal(s->regs.mem[a], 0); /* reserved and not applicable stay 0 */
            continue;
        }
        /* The host can never change the identity registers; the other read-only ones
         * report the motor's state. */
        if (d->access == REG_ACCESS_R && d->area == REG_AREA_EE)
            assert_memory_equal(&s->regs.mem[a], &factory[a], d->size);
    }
    assert_int_equal(regs_first_invalid(&s->regs), REGS_SIZE);
}

static void random_traffic_gets_only_well_formed_answers_from_its_own_id(void **state)
{
    (void)state;
    vbus_init(&bus);
    bus.step_us = 10; /* a slower main loop: enough for 9600 baud, and a fast test */
    vbus_add(&bus, &board_arm, 1);
    struct servo *s = &bus.node[0].servo;
    s->regs.mem[REG_RETURN_DELAY] = 0;
    link_latch(s);
    uint8_t factory[REGS_SIZE];
    memcpy(factory, s->regs.mem, sizeof factory);

    uint8_t pkt[300];
    for (int iter = 0; iter < 5000; iter++) {
        uint8_t id, ins;
        uint32_t n = random_packet(pkt, &id, &ins);
        if (rnd() % 16u == 0u) { /* garbage between packets */
            uint8_t junk[8];
            for (unsigned i = 0; i < sizeof junk; i++)
                junk[i] = (uint8_t)rnd();
            vbus_host_send(&bus, junk, sizeof junk);
        }
        vbus_host_send(&bus, pkt, n);
        /* Past any inter-byte time-out and the return delay (a random write may set it). */
        vbus_run_until(&bus, bus.now_us + 30000u + s->link.delay * 500u);
        /* Whatever answered: well-formed status packets from the servo's ID. */
        uint8_t ans[64];
        uint32_t len = 0, answered = 0;
        while (vbus_host_pending(&bus)) {
            const struct vbus_byte *w = vbus_host_next(&bus);
            assert_true(len < sizeof ans);
            ans[len++] = w->byte;
            answered++;
            if (len >= 4 && len == ans[3] + 4u) {
                assert_int_equal(ans[0], PROTO_HEADER0);
                assert_int_equal(ans[1], PROTO_HEADER1);
                assert_int_equal(ans[len - 1], proto_sum(&ans[2], (uint16_t)(len - 3u)));
                assert_int_not_equal(ans[2], PROTO_ID_BROADCAST);
                len = 0;
            }
        }
        assert_int_equal(len, 0);
        if (id == PROTO_ID_BROADCAST && ins != INS_PING && answered) {
            /* only a broadcast PING may be answered (a corrupted byte can turn a packet into
             * one for ID 1, so only check clean broadcasts) */
            uint8_t clean = proto_sum(&pkt[2], (uint16_t)(n - 3u)) == pkt[n - 1u];
            assert_false(clean && pkt[2] == PROTO_ID_BROADCAST && pkt[4] != INS_PING);
        }
        assert_table_sane(s, factory);
        if (s->link.id != 1u || s->link.baud != 9600u || s->link.delay) { /* bring it back */
            s->regs.mem[REG_ID] = 1;
            s->regs.mem[REG_BAUD_RATE] = 0;
            s->regs.mem[REG_RETURN_DELAY] = 0;
            link_latch(s);
        }
    }
    /* No collision check here: a corrupted LEN leaves bytes after what the servo takes
     * for the end of the packet, and a host still sending then talks over the answer,
     * which no servo can prevent. The replay transcripts check clean traffic for 0. */
}

/* Found by random_traffic_gets_only_well_formed_answers_from_its_own_id: L = 255 once wrapped the slice stride to 0 (a divide by
 * zero in the dispatcher). Such a SYNC WRITE is refused and changes nothing. */
static void sync_write_with_l_255(void **state)
{
    (void)state;
    vbus_init(&bus);
    vbus_add(&bus, &board_foot, 1);
    struct servo *s = &bus.node[0].servo;
    vbus_run_until(&bus, bus.now_us + 10000u); /* the present registers are written */
    uint8_t before[REGS_SIZE];
    memcpy(before, s->regs.mem, sizeof before);
    uint8_t pkt[] = {0xD5, 0x5D, 0xFE, 0x07, 0x83, 0x21, 0xFF, 0x01, 0x02, 0x03, 0};
    pkt[sizeof pkt - 1] = proto_sum(&pkt[2], (uint16_t)(sizeof pkt - 3u));
    vbus_host_send(&bus, pkt, sizeof pkt);
    vbus_run_until(&bus, bus.now_us + 30000u);
    assert_int_equal(vbus_host_pending(&bus), 0);
    assert_memory_equal(s->regs.mem, before, sizeof before);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(sync_write_with_l_255),
        cmocka_unit_test(random_traffic_gets_only_well_formed_answers_from_its_own_id),
    };
    return cmocka_run_group_tests(tests, 0, 0);
}
