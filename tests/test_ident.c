/* test_ident.c - the identity sub-command (CUSTOM 0x11, include/ident.h; issue 27) as a
 * host on the virtual bus sees it: several servos, duplicates among them, each with its
 * own hal_uid(). ENUMERATE's slots and their timing, IDENTIFY, SET ID by UID (kept
 * across a power cycle), and what stays as the vendor's protocol has it. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "board.h"
#include "ident.h"
#include "link.h"
#include "proto.h"
#include "update.h"
#include "vbus.h"

static struct vbus bus;

/* An answer as the host got it. */
struct answer {
    uint32_t start_us;
    uint8_t b[IDENT_ANSWER_BYTES];
};

static struct answer got[VBUS_NODES_MAX];
static unsigned ngot;
static unsigned other_bytes; /* servo bytes that were no whole identity answer */

static const uint8_t uid_a[12] = {0x13, 0x00, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x77};
static const uint8_t uid_b[12] = {0x25, 0x00, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x77};
static const uint8_t uid_c[12] = {0x3A, 0x01, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x77};

/* Three arms: a and b at ID 1 (a duplicate), c at ID 5; 9600 baud. */
static int setup(void **state)
{
    (void)state;
    vbus_init(&bus);
    vbus_add(&bus, &board_arm, 1);
    vbus_add(&bus, &board_arm, 1);
    vbus_add(&bus, &board_arm, 5);
    memcpy(bus.node[0].hal.uid, uid_a, 12);
    memcpy(bus.node[1].hal.uid, uid_b, 12);
    memcpy(bus.node[2].hal.uid, uid_c, 12);
    vbus_run_until(&bus, bus.now_us + 600000u); /* past the start's confirmation */
    while (vbus_host_pending(&bus))
        (void)vbus_host_next(&bus);
    return 0;
}

/* Send CUSTOM 0x11 op params to id; collect what servos send for `listen_ms`. Returns
 * the end of the request on the wire. */
static uint32_t ident(uint8_t id, const uint8_t *par, uint8_t n, uint32_t listen_ms)
{
    uint8_t p[40] = {IDENT_SUB};
    memcpy(&p[1], par, n);
    uint8_t pkt[64];
    uint16_t len = proto_build_packet(pkt, id, INS_CUSTOM, p, (uint8_t)(n + 1u));
    vbus_host_send(&bus, pkt, len);
    uint32_t end = bus.now_us;
    vbus_run_until(&bus, end + listen_ms * 1000u);
    ngot = 0;
    other_bytes = 0;
    while (vbus_host_pending(&bus)) {
        const struct vbus_byte *w = vbus_host_next(&bus);
        if (w->byte == PROTO_HEADER0 && ngot < VBUS_NODES_MAX &&
            vbus_host_pending(&bus) >= IDENT_ANSWER_BYTES - 1u) {
            got[ngot].start_us = w->start_us;
            got[ngot].b[0] = w->byte;
            for (unsigned i = 1; i < IDENT_ANSWER_BYTES; i++)
                got[ngot].b[i] = vbus_host_next(&bus)->byte;
            ngot++;
        } else {
            other_bytes++;
        }
    }
    return end;
}

/* The answer is well-formed, at ID 0xFF, of op, for the servo with uid, at ID id. */
static void assert_answer(const struct answer *a, uint8_t op, const uint8_t *uid, uint8_t id)
{
    const uint8_t *b = a->b;
    assert_int_equal(b[0], PROTO_HEADER0);
    assert_int_equal(b[1], PROTO_HEADER1);
    assert_int_equal(b[2], 0xFF);
    assert_int_equal(b[3], IDENT_ANSWER_DATA + 2u);
    assert_int_equal(b[4], 0); /* ERR: no fault */
    assert_int_equal(b[5], op);
    assert_memory_equal(&b[6], uid, 12);
    assert_int_equal(b[18], id);
    assert_int_equal(b[19], VARIANT_ARM);
    assert_int_equal(b[20] | b[21] << 8, BOARD_MODEL_ARM);
    assert_int_equal(b[22], 0); /* baud code: factory */
    for (unsigned i = 0; i < 12; i++)
        assert_int_equal(b[23 + i], (uint8_t)~uid[i]);
    assert_int_equal(proto_sum(&b[2], IDENT_ANSWER_BYTES - 3u), b[IDENT_ANSWER_BYTES - 1u]);
}

static const struct answer *answer_of(const uint8_t *uid)
{
    for (unsigned i = 0; i < ngot; i++)
        if (memcmp(&got[i].b[6], uid, 12) == 0)
            return &got[i];
    return NULL;
}

static void enumerate_answers_every_servo_in_its_nibble_slot(void **state)
{
    (void)state;
    uint8_t k0[] = {IDENT_ENUMERATE, 0};
    uint32_t end = ident(PROTO_ID_BROADCAST, k0, 2, 900);
    assert_int_equal(ngot, 3);
    assert_int_equal(other_bytes, 0);
    assert_int_equal(bus.collisions, 0);
    uint32_t slot = ident_slot_us(9600);
    const uint8_t *uids[] = {uid_a, uid_b, uid_c};
    const uint8_t ids[] = {1, 1, 5};
    for (unsigned i = 0; i < 3; i++) {
        const struct answer *a = answer_of(uids[i]);
        assert_non_null(a);
        assert_answer(a, IDENT_ENUMERATE, uids[i], ids[i]);
        /* its slot: nibble 0 of its UID (a 3, b 5, c 10) */
        uint32_t want = end + IDENT_TURNAROUND_US + (uids[i][0] & 0x0Fu) * slot;
        assert_in_range(a->start_us - want, 0, 40); /* + the main loop's latency */
    }
}

static void enumerate_prefix_narrows_and_nothing_but_broadcast_counts(void **state)
{
    (void)state;
    /* k = 1: the servos under nibble 0 = 3 (a alone) answer in slot nibble 1 (1) */
    uint8_t k1[] = {IDENT_ENUMERATE, 1, 0x03};
    uint32_t end = ident(PROTO_ID_BROADCAST, k1, 3, 900);
    assert_int_equal(ngot, 1);
    assert_non_null(answer_of(uid_a));
    assert_in_range(got[0].start_us - (end + IDENT_TURNAROUND_US + 1u * ident_slot_us(9600)),
                    0, 40);
    uint8_t k1c[] = {IDENT_ENUMERATE, 1, 0x0A}; /* c: nibble 1 = 3 */
    end = ident(PROTO_ID_BROADCAST, k1c, 3, 900);
    assert_int_equal(ngot, 1);
    assert_non_null(answer_of(uid_c));
    assert_in_range(got[0].start_us - (end + IDENT_TURNAROUND_US + 3u * ident_slot_us(9600)),
                    0, 40);
    /* k = 3 (two bytes of prefix, the last nibble counted): c, then nobody */
    uint8_t k3[] = {IDENT_ENUMERATE, 3, 0x3A, 0x01};
    ident(PROTO_ID_BROADCAST, k3, 4, 900);
    assert_int_equal(ngot, 1);
    assert_non_null(answer_of(uid_c));
    uint8_t k3x[] = {IDENT_ENUMERATE, 3, 0x3A, 0x02};
    ident(PROTO_ID_BROADCAST, k3x, 4, 900);
    assert_int_equal(ngot + other_bytes, 0);
    /* ignored: to one ID, a wrong prefix length, k = 24, no k at all */
    uint8_t to_one[] = {IDENT_ENUMERATE, 0};
    ident(1, to_one, 2, 900);
    assert_int_equal(ngot + other_bytes, 0);
    uint8_t bad_len[] = {IDENT_ENUMERATE, 2, 0x33};
    ident(PROTO_ID_BROADCAST, bad_len, 3, 900);
    assert_int_equal(ngot + other_bytes, 0);
    uint8_t k24[14] = {IDENT_ENUMERATE, 24};
    ident(PROTO_ID_BROADCAST, k24, 14, 900);
    assert_int_equal(ngot + other_bytes, 0);
    uint8_t no_k[] = {IDENT_ENUMERATE};
    ident(PROTO_ID_BROADCAST, no_k, 1, 900);
    assert_int_equal(ngot + other_bytes, 0);
}

static void identify_by_id_and_by_uid(void **state)
{
    (void)state;
    uint8_t by_id[] = {IDENT_IDENTIFY};
    uint32_t end = ident(5, by_id, 1, 100);
    assert_int_equal(ngot, 1);
    assert_answer(&got[0], IDENT_IDENTIFY, uid_c, 5);
    assert_in_range(got[0].start_us - (end + IDENT_TURNAROUND_US), 0, 40);
    ident(PROTO_ID_BROADCAST, by_id, 1, 100); /* by ID at broadcast: nobody */
    assert_int_equal(ngot + other_bytes, 0);
    uint8_t by_uid[13] = {IDENT_IDENTIFY};
    memcpy(&by_uid[1], uid_b, 12);
    ident(PROTO_ID_BROADCAST, by_uid, 13, 100); /* b alone, though a shares its ID */
    assert_int_equal(ngot, 1);
    assert_int_equal(other_bytes, 0);
    assert_answer(&got[0], IDENT_IDENTIFY, uid_b, 1);
    ident(5, by_uid, 13, 100); /* b is not at ID 5 */
    assert_int_equal(ngot + other_bytes, 0);
}

static void set_id_by_uid_moves_that_servo_alone_and_it_stays(void **state)
{
    (void)state;
    uint8_t set[14] = {IDENT_SET_ID};
    memcpy(&set[1], uid_b, 12);
    set[13] = 9;
    ident(PROTO_ID_BROADCAST, set, 14, 200);
    assert_int_equal(ngot + other_bytes, 0); /* none answers at broadcast */
    assert_int_equal(link_id(&bus.node[1].servo.link), 9);
    assert_int_equal(link_id(&bus.node[0].servo.link), 1); /* a stays at 1 */
    /* addressed to its ID: it answers, with the new ID */
    memcpy(&set[1], uid_a, 12);
    set[13] = 7;
    ident(1, set, 14, 200);
    assert_int_equal(ngot, 1);
    assert_answer(&got[0], IDENT_SET_ID, uid_a, 7);
    assert_int_equal(link_id(&bus.node[0].servo.link), 7);
    /* an ID out of range is refused like a WRITE of it: no change, no answer */
    set[13] = 0xFE;
    ident(7, set, 14, 200);
    assert_int_equal(ngot + other_bytes, 0);
    assert_int_equal(link_id(&bus.node[0].servo.link), 7);
    /* kept in flash: a power cycle keeps both */
    vbus_run_until(&bus, bus.now_us + 300000u);
    vbus_power_cycle(&bus, 0);
    vbus_power_cycle(&bus, 1);
    vbus_run_until(&bus, bus.now_us + 100000u);
    assert_int_equal(link_id(&bus.node[0].servo.link), 7);
    assert_int_equal(link_id(&bus.node[1].servo.link), 9);
}

/* The vendor's protocol where 0x11 brings nothing: a CUSTOM with sub 0x11 and no op is
 * refused as before (reported with register 18 bit 5: factory on). */
static void sub_0x11_without_an_op_is_an_instruction_error_as_before(void **state)
{
    (void)state;
    uint8_t p[] = {IDENT_SUB};
    uint8_t pkt[16];
    uint16_t len = proto_build_packet(pkt, 5, INS_CUSTOM, p, 1);
    vbus_host_send(&bus, pkt, len);
    vbus_run_until(&bus, bus.now_us + 100000u);
    uint8_t b[8];
    unsigned n = 0;
    while (vbus_host_pending(&bus) && n < sizeof b)
        b[n++] = vbus_host_next(&bus)->byte;
    assert_int_equal(n, 6);
    assert_int_equal(b[2], 5);
    assert_int_equal(b[4] & ERR_INSTRUCTION, ERR_INSTRUCTION);
}

/* During a §10 update session the servo only reports (PROTOCOL.md §10): the identity
 * sub is refused as any other instruction (an instruction error at its ID when
 * addressed), and a SET ID by its UID changes nothing. */
static void an_update_session_refuses_identity_ops(void **state)
{
    (void)state;
    uint8_t pkt[16];
    uint8_t enter = PROTO_UPDATE_SUB_ENTER;
    uint16_t len = proto_build_packet(pkt, 5, INS_CUSTOM, &enter, 1);
    vbus_host_send(&bus, pkt, len);
    vbus_run_until(&bus, bus.now_us + 100000u);
    while (vbus_host_pending(&bus))
        (void)vbus_host_next(&bus);
    assert_true(update_in_session(&bus.node[2].servo.update));
    uint8_t op = IDENT_IDENTIFY;
    ident(5, &op, 1, 100);
    assert_int_equal(ngot, 0);
    assert_int_equal(other_bytes, 6); /* D5 5D 05 02 ERR CHK */
    uint8_t set[14] = {IDENT_SET_ID};
    memcpy(&set[1], uid_c, 12);
    set[13] = 9;
    ident(PROTO_ID_BROADCAST, set, 14, 200);
    assert_int_equal(ngot + other_bytes, 0);
    assert_int_equal(link_id(&bus.node[2].servo.link), 5);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(enumerate_answers_every_servo_in_its_nibble_slot, setup),
        cmocka_unit_test_setup(enumerate_prefix_narrows_and_nothing_but_broadcast_counts, setup),
        cmocka_unit_test_setup(identify_by_id_and_by_uid, setup),
        cmocka_unit_test_setup(set_id_by_uid_moves_that_servo_alone_and_it_stays, setup),
        cmocka_unit_test_setup(sub_0x11_without_an_op_is_an_instruction_error_as_before, setup),
        cmocka_unit_test_setup(an_update_session_refuses_identity_ops, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
