/* test_loader.c - update mode (loader.h), what a user meets when a servo has no valid
 * application: it listens at the ID, baud and return delay the application stored (or
 * the factory ones), read from the store without the register table; it answers the §10
 * frames addressed to it and nothing else; and the application, sharing the same answer,
 * answers the §10 handshake at every status return level. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "loader.h"
#include "proto.h"
#include "regs.h"
#include "wire_servo.h"

static struct wire_servo w = {.board = &board_arm};

/* A servo whose application slot is erased: the bootloader stays in update mode. */
static void power_on_without_application(void)
{
    hal_host_init(&w.hal);
    hal_host_attach_board(&w.hal, w.board);
    w.resets = 0;
    wire_power_on(&w);
    assert_true(loader_running(&w.s.loader));
}

/* The application's settings, stored as the application stores them: set, then its main
 * loop commits them to flash. */
static void application_stores(const struct board *b, uint8_t id, uint8_t baud_code,
                               uint8_t delay)
{
    struct servo s;
    hal_host_init(&w.hal);
    servo_init(&s, b, &w.hal);
    regs_set(&s.regs, REG_ID, id);
    regs_set(&s.regs, REG_BAUD_RATE, baud_code);
    regs_set(&s.regs, REG_RETURN_DELAY, delay);
    servo_poll(&s);
}

static uint16_t xfer(uint8_t id, uint8_t ins, const uint8_t *p, uint8_t n, uint8_t *ans)
{
    uint8_t out[16];
    uint16_t len = proto_build_packet(out, id, ins, p, n);
    return wire_xfer(&w, out, len, ans);
}

/* The §10 handshake: D5 5D ID 03 FF FC CHK (the byte after LEN is CUSTOM's 0xFF). */
static const uint8_t enter = PROTO_UPDATE_SUB_ENTER;

/* The §10 handshake's answer: D5 5D ID 03 00 43 CHK ('C', ERR 0). */
static void assert_answered_c(const uint8_t *ans, uint16_t n, uint8_t id)
{
    uint8_t want[8];
    const uint8_t c = 0x43;
    uint16_t len = proto_build_packet(want, id, 0, &c, 1);
    assert_int_equal(n, len);
    assert_memory_equal(ans, want, len);
}

static void an_empty_store_means_the_factory_settings(void **state)
{
    (void)state;
    for (uint32_t b = 0; b < BOARD_COUNT; b++) {
        hal_host_init(&w.hal);
        struct loader_settings set;
        loader_settings(&w.hal, board_all[b], &set);
        assert_int_equal(set.id, REGS_FACTORY_ID);
        assert_int_equal(set.baud_code, 0);
        assert_int_equal(set.delay, board_all[b]->return_delay);
    }
}

/* ID 7, 38400 baud, delay 20 x 500 us, stored by the application: update mode listens
 * there, on every board. */
static void update_mode_listens_where_the_application_stored(void **state)
{
    (void)state;
    for (uint32_t b = 0; b < BOARD_COUNT; b++) {
        application_stores(board_all[b], 7, 3, 20);
        struct loader_settings set;
        loader_settings(&w.hal, board_all[b], &set);
        assert_int_equal(set.id, 7);
        assert_int_equal(set.baud_code, 3);
        assert_int_equal(set.delay, 20);
        struct servo s;
        loader_init(&s, board_all[b], &w.hal);
        assert_int_equal(link_id(&s.link), 7);
        assert_int_equal(loader_running(&s.loader), 1);
    }
}

/* Values no register takes (a foreign or damaged store) fall back to the factory's: ID
 * 254 (the broadcast ID is 254, one servo's highest 253), baud code 11 (no such rate);
 * a delay of 0 is a delay like any other. */
static void stored_values_out_of_range_fall_back_to_the_factory(void **state)
{
    (void)state;
    application_stores(&board_foot, PROTO_ID_MAX + 1u, 11, 0);
    struct loader_settings set;
    loader_settings(&w.hal, &board_foot, &set);
    assert_int_equal(set.id, REGS_FACTORY_ID);
    assert_int_equal(set.baud_code, 0);
    assert_int_equal(set.delay, 0);
}

/* Update mode answers the handshake at its own ID only: not another ID, not the
 * broadcast ID, and no PING or READ (the motor side is not there). */
static void update_mode_answers_only_update_frames_to_its_id(void **state)
{
    (void)state;
    power_on_without_application();
    uint8_t ans[64];
    assert_int_equal(xfer(2, INS_CUSTOM, &enter, 1, ans), 0);
    assert_int_equal(xfer(PROTO_ID_BROADCAST, INS_CUSTOM, &enter, 1, ans), 0);
    assert_int_equal(xfer(1, INS_PING, NULL, 0, ans), 0);
    const uint8_t rd[2] = {REG_ID, 1};
    assert_int_equal(xfer(1, INS_READ, rd, 2, ans), 0);
    uint16_t n = xfer(1, INS_CUSTOM, &enter, 1, ans);
    assert_answered_c(ans, n, 1);
}

/* The application hands §10 frames to the same answer: at status return level 0, where
 * not even a READ is answered, the handshake still is. */
static void the_application_answers_the_handshake_at_level_0(void **state)
{
    (void)state;
    wire_factory(&w);
    assert_false(loader_running(&w.s.loader));
    uint8_t ans[64];
    const uint8_t level0[2] = {REG_STATUS_RETURN_LEVEL, 0};
    assert_int_not_equal(xfer(1, INS_WRITE, level0, 2, ans), 0); /* at the level before */
    const uint8_t rd[2] = {REG_ID, 1};
    assert_int_equal(xfer(1, INS_READ, rd, 2, ans), 0);
    uint16_t n = xfer(1, INS_CUSTOM, &enter, 1, ans);
    assert_answered_c(ans, n, 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(an_empty_store_means_the_factory_settings),
        cmocka_unit_test(update_mode_listens_where_the_application_stored),
        cmocka_unit_test(stored_values_out_of_range_fall_back_to_the_factory),
        cmocka_unit_test(update_mode_answers_only_update_frames_to_its_id),
        cmocka_unit_test(the_application_answers_the_handshake_at_level_0),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
