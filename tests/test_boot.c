/* test_boot.c - boot confirmation (boot.h, docs/update.md): the bootloader counts the
 * starts an application did not confirm and, after BOOT_STARTS_MAX of them, stays in
 * update mode. On a host servo: an image that hangs at start (the host image model,
 * IMAGE_HOST_HANG) is started three times, then the servo waits in update mode, across
 * power cycles, until a good image is sent, which installs and confirms; a good image
 * confirms at its first answer or after BOOT_CONFIRM_US and never falls back. On the
 * record alone: every torn mark and torn erase is read the right way, and a power cut
 * at every flash operation of 150 starts, of an install, never locks a good image out. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "boot.h"
#include "crc.h"
#include "hal_host.h"
#include "image.h"
#include "proto.h"
#include "servo.h"
#include "update.h"
#include "update_wire.h"
#include "wire_servo.h"

#define WIRE_MAX (4u + FRAME_BLOCK_BYTES)

static struct wire_servo w = {.board = &board_arm};
static const struct board *const arm = &board_arm;

/* ---- the record ---------------------------------------------------------------------- */

static uint16_t unconfirmed(void)
{
    uint16_t end;
    return boot_unconfirmed(&w.hal, &end);
}

static uint16_t record_end(void)
{
    uint16_t end;
    (void)boot_unconfirmed(&w.hal, &end);
    return end;
}

static const uint8_t *record(void)
{
    return w.hal.flash.mem[HAL_PAGE_BOOTREC];
}

static bool record_blank(void)
{
    for (uint16_t i = 0; i < HAL_FLASH_PAGE_BYTES; i++)
        if (record()[i] != 0xFFu)
            return false;
    return true;
}

/* Marks past the first erased half-word (what a torn erase leaves). */
static bool record_dirty(void)
{
    for (uint16_t i = (uint16_t)(record_end() + 2u); i < HAL_FLASH_PAGE_BYTES; i++)
        if (record()[i] != 0xFFu)
            return true;
    return false;
}

static void put_mark(uint16_t off, uint16_t v)
{
    w.hal.flash.mem[HAL_PAGE_BOOTREC][off] = (uint8_t)v;
    w.hal.flash.mem[HAL_PAGE_BOOTREC][off + 1u] = (uint8_t)(v >> 8);
}

/* A blank flash with a small valid application (the record tests run the bootloader's
 * image check at every start: a short image keeps that cheap). */
static void small_app(void)
{
    static uint8_t app[1100];
    hal_host_init(&w.hal);
    hal_host_image_build(app, sizeof app, arm->model_number, 1, 2);
    hal_host_program_app(&w.hal, app, sizeof app);
    /* The boot_start() calls of these tests stand for starts the watchdog ended: the
     * ones that count (a start the power ended does not: see the bus tests). */
    w.hal.power_reset = false;
}

/* ---- a servo on the bus ---------------------------------------------------------------- */

static void run(uint32_t us)
{
    for (uint32_t t = 0; t < us; t += 1000u)
        wire_step(&w, 1000);
}

static bool pinged(uint8_t id)
{
    uint8_t pkt[8], ans[64];
    uint16_t len = proto_build_packet(pkt, id, INS_PING, 0, 0);
    return wire_xfer(&w, pkt, len, ans) == 7u;
}

static uint8_t version_of(uint8_t id)
{
    uint8_t pkt[8], ans[64];
    const uint8_t params[2] = {REG_FIRMWARE_VERSION, 1};
    uint16_t len = proto_build_packet(pkt, id, INS_READ, params, 2);
    assert_int_equal(wire_xfer(&w, pkt, len, ans), 7u);
    return ans[5];
}

/* ---- §10 frames (update_wire.h) ---------------------------------- */

static uint8_t wire[WIRE_MAX];

/* Send and require exactly the status packet `D5 5D id LEN 00 data CHK`. */
static void expect_answer(uint16_t n, uint8_t id, const uint8_t *data, uint8_t dn)
{
    uint8_t ans[64], want[16];
    uint16_t wn = proto_build_packet(want, id, 0, data, dn);
    uint16_t got = wire_xfer(&w, wire, n, ans);
    assert_int_equal(got, wn);
    assert_memory_equal(ans, want, wn);
}

static const uint8_t ACK[] = {UPDATE_ACK}, ACK_C[] = {UPDATE_ACK, UPDATE_READY};
static const uint8_t READY[] = {UPDATE_READY};

static void send_enter(uint8_t id)
{
    expect_answer(enter_frame(wire, id), id, READY, 1);
}

/* A whole good session of img to id, up to and including the end-of-batch ACK. */
static void send_image(uint8_t id, const uint8_t *img, uint32_t len)
{
    send_enter(id);
    expect_answer(header_frame(wire, id, len), id, ACK_C, 2);
    for (uint8_t b = 1; b <= blocks_of(len); b++)
        expect_answer(data_frame(wire, id, img, len, b), id, ACK, 1);
    expect_answer(eof_frame(wire, id), id, ACK_C, 2);
    expect_answer(batch_end_frame(wire, id), id, ACK, 1);
}

#define IMG_LEN 3000u
static uint8_t img[IMG_LEN];

/* ---- the marks --------------------------------------------------------------------------- */

/* A torn program leaves some of the bits it was clearing at 1; a torn erase sets some of
 * the bits at 0 to 1. Either way a START reads as a START or as erased, a CONFIRM as a
 * CONFIRM or as erased: every such value, exhaustively. */
static void test_torn_marks_keep_their_kind(void **state)
{
    (void)state;
    hal_host_init(&w.hal);
    for (uint32_t x = 0; x < 0x100u; x++) {
        memset(w.hal.flash.mem[HAL_PAGE_BOOTREC], 0xFF, HAL_FLASH_PAGE_BYTES);
        put_mark(0, BOOT_MARK_CONFIRM); /* a confirmed start before */
        put_mark(2, BOOT_MARK_START);
        put_mark(4, (uint16_t)(BOOT_MARK_START | x)); /* a START, torn */
        assert_int_equal(unconfirmed(), x == 0xFFu ? 1u : 2u);
        assert_int_equal(record_end(), x == 0xFFu ? 4u : 6u);
        put_mark(4, (uint16_t)(BOOT_MARK_CONFIRM | (x << 8))); /* a CONFIRM, torn */
        assert_int_equal(unconfirmed(), x == 0xFFu ? 1u : 0u);
        assert_int_equal(record_end(), x == 0xFFu ? 4u : 6u);
    }
}

/* The log: a start mark before each start, a confirm after it; erased, it counts none. */
static void test_start_and_confirm_marks(void **state)
{
    (void)state;
    wire_factory(&w); /* power_on: boot_start wrote the first START */
    assert_int_equal(unconfirmed(), 1);
    assert_int_equal(record()[0] | record()[1] << 8, BOOT_MARK_START);
    assert_true(boot_confirm(&w.hal, false));
    assert_int_equal(unconfirmed(), 0);
    assert_int_equal(record()[2] | record()[3] << 8, BOOT_MARK_CONFIRM);
    assert_int_equal(record_end(), 4);
    assert_true(boot_confirm(&w.hal, false)); /* nothing to confirm: nothing written */
    assert_int_equal(record_end(), 4);
    /* Three starts with no confirm, each ended by the watchdog: the fourth is refused,
     * the image stays installed. */
    w.hal.power_reset = false;
    for (uint16_t n = 1; n <= BOOT_STARTS_MAX; n++) {
        assert_true(boot_start(&w.hal, arm->model_number));
        assert_int_equal(unconfirmed(), n);
    }
    uint32_t ops = w.hal.flash.ops;
    assert_false(boot_start(&w.hal, arm->model_number));
    assert_int_equal(w.hal.flash.ops, ops); /* refusing writes nothing */
    assert_true(image_valid(&w.hal, HAL_PAGE_APP, arm->model_number, 0));
}

/* ---- a good image -------------------------------------------------------------------- */

/* Confirmed once its first answer has left the wire: not while it is being sent. */
static void test_good_image_confirms_at_first_answer(void **state)
{
    (void)state;
    wire_factory(&w);
    assert_false(loader_running(&w.s.loader));
    assert_true(w.hal.watchdog_started); /* the bootloader's, before the jump */
    run(50000);
    assert_int_equal(unconfirmed(), 1);
    uint8_t pkt[8];
    uint16_t n = proto_build_packet(pkt, 1, INS_PING, 0, 0);
    for (uint16_t i = 0; i < n; i++) {
        w.hal.now_us += WIRE_BYTE_US;
        servo_rx_isr(&w.s, pkt[i]);
        servo_step(&w.s);
    }
    uint32_t sent = w.hal.sends;
    while (w.hal.sends == sent) /* the return delay */
        wire_step(&w, 100);
    while (hal_uart_tx_busy(&w.hal)) {
        assert_int_equal(unconfirmed(), 1); /* the answer is still on the wire */
        wire_step(&w, 100);
    }
    wire_step(&w, 100);
    assert_int_equal(unconfirmed(), 0);
    assert_true(w.s.confirmed);
}

/* With nobody talking to it, it confirms after BOOT_CONFIRM_US of its main loop. */
static void test_good_image_confirms_after_a_while(void **state)
{
    (void)state;
    wire_factory(&w);
    run(BOOT_CONFIRM_US - 10000u);
    assert_int_equal(unconfirmed(), 1);
    assert_false(w.s.confirmed);
    run(20000);
    assert_int_equal(unconfirmed(), 0);
    assert_true(w.s.confirmed);
    assert_int_equal(w.resets, 0);
}

/* 400 power cycles, confirmed either way: never update mode; the application erases the
 * record once it is half full, so it never fills. */
static void test_good_image_never_falls_back(void **state)
{
    (void)state;
    wire_factory(&w);
    uint32_t erases = w.hal.flash.erases[HAL_PAGE_BOOTREC];
    for (uint32_t i = 0; i < 400u; i++) {
        assert_false(loader_running(&w.s.loader));
        assert_int_equal(unconfirmed(), 1);
        if (i % 2u)
            assert_true(pinged(1));
        else
            run(BOOT_CONFIRM_US + 1000u);
        assert_int_equal(unconfirmed(), 0);
        assert_true(record_end() < BOOT_TIDY_BYTES + 4u);
        wire_power_on(&w);
    }
    assert_int_equal(w.hal.flash.erases[HAL_PAGE_BOOTREC] - erases, 400u / (BOOT_TIDY_BYTES / 4u));
    assert_int_equal(w.resets, 0);
}

/* ---- an image that hangs at start ------------------------------------------------------ */

/* Installed over the bus, it hangs: the watchdog w.resets it three times, then the servo
 * stays in update mode, also across power cycles, answering only the update; a good
 * image then installs, starts and confirms. */
static void test_hanging_image_leaves_update_mode_reachable(void **state)
{
    (void)state;
    wire_factory(&w);
    assert_true(pinged(1));
    hal_host_image_build(img, IMG_LEN, arm->model_number, 7, 3);
    hal_host_image_hang(img, IMG_LEN);
    assert_true(image_valid(&w.hal, HAL_PAGE_APP, arm->model_number, 0));
    send_image(1, img, IMG_LEN);
    wire_step(&w, 50000); /* the ACK is out: restart, install, start it */
    assert_int_equal(w.resets, 1);
    assert_true(w.hal.image_hung);
    assert_true(image_valid(&w.hal, HAL_PAGE_APP, arm->model_number, 0)); /* a valid image */
    assert_int_equal(unconfirmed(), 1); /* the install emptied the record */
    for (uint16_t start = 2; start <= BOOT_STARTS_MAX; start++) {
        run(SERVO_WATCHDOG_US); /* never fed: the watchdog w.resets it */
        assert_int_equal(w.resets, start);
        assert_true(w.hal.image_hung);
        assert_int_equal(unconfirmed(), start);
    }
    run(SERVO_WATCHDOG_US);
    assert_true(loader_running(&w.s.loader)); /* the fourth boot: update mode */
    assert_true(w.hal.watchdog_started);
    uint32_t r = w.resets;
    run(2000000);
    assert_int_equal(w.resets, r); /* it stays there, fed */
    /* A power cycle gives the image another try (a start the power ended proves
     * nothing); the watchdog ends three more, and update mode is back. */
    wire_power_on(&w);
    assert_true(w.hal.image_hung);
    assert_int_equal(unconfirmed(), 1);
    run(BOOT_STARTS_MAX * SERVO_WATCHDOG_US + SERVO_WATCHDOG_US / 2);
    assert_true(loader_running(&w.s.loader));
    assert_int_equal(unconfirmed(), BOOT_STARTS_MAX);
    /* What the host sees: PING unanswered, the §10 handshake answered 'C'. */
    assert_false(pinged(1));
    send_enter(1);
    hal_host_image_build(img, IMG_LEN, arm->model_number, 8, 4);
    send_image(1, img, IMG_LEN);
    wire_step(&w, 50000);
    assert_false(loader_running(&w.s.loader));
    assert_false(w.hal.image_hung);
    assert_int_equal(unconfirmed(), 1);
    assert_int_equal(version_of(1), 8);
    assert_int_equal(unconfirmed(), 0); /* confirmed by that answer */
    wire_power_on(&w);
    assert_false(loader_running(&w.s.loader));
}

/* The same image programmed at the factory (no install to empty the record). */
static void test_hanging_factory_image(void **state)
{
    (void)state;
    hal_host_init(&w.hal);
    hal_host_attach_board(&w.hal, arm);
    static uint8_t big[HAL_HOST_FACTORY_BYTES];
    hal_host_image_build(big, sizeof big, arm->model_number, SERVO_FW_VERSION, 1);
    hal_host_image_hang(big, sizeof big);
    hal_host_program_app(&w.hal, big, sizeof big);
    w.resets = 0;
    wire_power_on(&w);
    run(5 * SERVO_WATCHDOG_US);
    assert_int_equal(w.resets, BOOT_STARTS_MAX);
    assert_true(loader_running(&w.s.loader));
}

/* A start the power cut short (a robot switched off within BOOT_CONFIRM_US, before any
 * answer) is not a failed start: only the watchdog or a fault ending a start counts
 * (hal_reset_by_power). Any number of short power-ups leave a good image running. */
static void test_short_power_ups_never_lock_a_good_image(void **state)
{
    (void)state;
    wire_factory(&w);
    for (int i = 0; i < 3 * (int)BOOT_STARTS_MAX; i++) {
        run(1000000);
        wire_power_on(&w);
        assert_false(loader_running(&w.s.loader));
        assert_int_equal(unconfirmed(), 1); /* this start only */
    }
    assert_true(pinged(1));
}

/* ---- the record's erases ---------------------------------------------------------------- */

/* Half full: the confirm is written at once, the erase waits until the servo is quiet. */
static void test_tidy_waits_for_quiet(void **state)
{
    (void)state;
    small_app();
    for (uint16_t off = 0; off < BOOT_TIDY_BYTES; off += 4u) {
        put_mark(off, BOOT_MARK_START);
        put_mark((uint16_t)(off + 2u), BOOT_MARK_CONFIRM);
    }
    assert_true(boot_start(&w.hal, arm->model_number));
    assert_int_equal(unconfirmed(), 1);
    assert_false(boot_confirm(&w.hal, false));
    assert_int_equal(unconfirmed(), 0);
    assert_int_equal(record_end(), BOOT_TIDY_BYTES + 4u);
    assert_false(boot_confirm(&w.hal, false));
    assert_int_equal(record_end(), BOOT_TIDY_BYTES + 4u); /* not written twice */
    assert_true(boot_confirm(&w.hal, true));
    assert_true(record_blank());
}

/* Full (nothing erased it): the start goes uncounted, the application erases it. */
static void test_full_record(void **state)
{
    (void)state;
    small_app();
    for (uint16_t off = 0; off < HAL_FLASH_PAGE_BYTES; off += 4u) {
        put_mark(off, BOOT_MARK_START);
        put_mark((uint16_t)(off + 2u), BOOT_MARK_CONFIRM);
    }
    uint32_t ops = w.hal.flash.ops;
    assert_true(boot_start(&w.hal, arm->model_number));
    assert_int_equal(w.hal.flash.ops, ops);
    assert_true(boot_confirm(&w.hal, true));
    assert_true(record_blank());
}

/* What a torn erase leaves past the end of the log: marks written up to it join it to
 * the log, where they may read as starts, so the confirm is written again past them;
 * marks further away are erased by the next confirm, once the servo is quiet. */
static void test_torn_erase_leftovers(void **state)
{
    (void)state;
    small_app();
    put_mark(0, BOOT_MARK_START);
    put_mark(2, BOOT_MARK_CONFIRM);
    put_mark(8, BOOT_MARK_START); /* survivors past two erased half-words */
    put_mark(10, BOOT_MARK_START);
    assert_true(boot_start(&w.hal, arm->model_number));
    assert_int_equal(record_end(), 6);
    assert_int_equal(unconfirmed(), 1);
    assert_true(record_dirty());
    assert_true(boot_confirm(&w.hal, false)); /* C at 6 joins 8 and 10; C again at 12 */
    assert_int_equal(unconfirmed(), 0);
    assert_int_equal(record_end(), 14);
    assert_false(record_dirty());

    memset(w.hal.flash.mem[HAL_PAGE_BOOTREC], 0xFF, HAL_FLASH_PAGE_BYTES);
    put_mark(0, BOOT_MARK_START);
    put_mark(2, BOOT_MARK_CONFIRM);
    put_mark(10, BOOT_MARK_START); /* further away: not reached */
    assert_true(boot_start(&w.hal, arm->model_number));
    assert_false(boot_confirm(&w.hal, false));
    assert_int_equal(unconfirmed(), 0);
    assert_int_equal(record_end(), 8);
    assert_true(record_dirty());
    assert_true(boot_confirm(&w.hal, true));
    assert_true(record_blank());
}

/* ---- power cuts ---------------------------------------------------------------------- */

/* One start as the bootloader and a good application make it: the start mark, then the
 * confirm (and the erase when due), with the servo always quiet. A cut ends the boot. */
static bool one_boot(void)
{
    bool started = boot_start(&w.hal, arm->model_number);
    if (started)
        while (w.hal.flash.powered && !boot_confirm(&w.hal, true)) {
        }
    return started;
}

#define HISTORY 150u /* starts: past BOOT_TIDY_BYTES once (one erase) */

/* A cut at every flash operation of HISTORY good starts, in each of the three ways:
 * every start still starts the application, and once the next start is confirmed the
 * record counts none and holds nothing past its end. */
static void test_power_cut_at_every_record_operation(void **state)
{
    (void)state;
    small_app();
    static uint8_t blank_record[HAL_FLASH_PAGE_BYTES];
    memset(blank_record, 0xFF, sizeof blank_record);
    w.hal.flash.ops = 0;
    for (uint32_t i = 0; i < HISTORY; i++)
        assert_true(one_boot());
    uint32_t total = w.hal.flash.ops;
    assert_int_equal(total, 2u * HISTORY + 1u); /* a start, a confirm each, one erase */

    uint32_t scenarios = 0;
    for (uint8_t kind = FLASH_CUT_CLEAN; kind <= FLASH_CUT_TORN; kind++) {
        for (uint32_t k = 1; k <= total; k++) {
            memcpy(w.hal.flash.mem[HAL_PAGE_BOOTREC], blank_record, HAL_FLASH_PAGE_BYTES);
            flash_sim_power_on(&w.hal.flash);
            w.hal.flash.cut_kind = kind;
            w.hal.flash.cut_at = k;
            for (uint32_t i = 0; i < HISTORY; i++) {
                uint16_t before = unconfirmed();
                if (!one_boot())
                    fail_msg("cut %u (kind %u) at operation %u: start %u refused", scenarios,
                             kind, k, i);
                if (!w.hal.flash.powered) { /* this boot ended in the cut */
                    flash_sim_power_on(&w.hal.flash);
                    if (unconfirmed() > before + 1u)
                        fail_msg("cut at operation %u (kind %u): %u unconfirmed, was %u", k,
                                 kind, unconfirmed(), before);
                }
            }
            assert_true(one_boot());
            assert_true(one_boot());
            assert_int_equal(unconfirmed(), 0);
            assert_false(record_dirty());
            scenarios++;
        }
    }
    print_message("record power cuts: %u scenarios (%u operations x 3)\n", scenarios, total);
}

/* After two failed starts a cut while writing the third start's mark counts as a start
 * (as a cut anywhere before the confirm would): at most one count per cut. */
static void test_cut_counts_at_most_one_start(void **state)
{
    (void)state;
    for (uint8_t kind = FLASH_CUT_CLEAN; kind <= FLASH_CUT_TORN; kind++) {
        for (uint32_t trial = 0; trial < 64u; trial++) {
            small_app();
            w.hal.flash.rng ^= trial * 0x9E3779B9u; /* other torn bits each trial */
            assert_true(boot_start(&w.hal, arm->model_number));
            assert_true(boot_start(&w.hal, arm->model_number));
            w.hal.flash.ops = 0;
            w.hal.flash.cut_kind = kind;
            w.hal.flash.cut_at = 1;
            (void)boot_start(&w.hal, arm->model_number);
            flash_sim_power_on(&w.hal.flash);
            uint16_t n = unconfirmed();
            assert_true(n == 2u || n == 3u);
            if (kind == FLASH_CUT_CLEAN)
                assert_int_equal(n, 2);
            if (kind == FLASH_CUT_DONE)
                assert_int_equal(n, 3);
            assert_int_equal(boot_start(&w.hal, arm->model_number), n < BOOT_STARTS_MAX);
        }
    }
}

/* A locked servo (three unconfirmed starts) with a verified image staged: a cut at every
 * flash operation of the install, three ways; when the power is back the new image is
 * installed and starts with a fresh record. */
static void test_install_empties_record_through_cuts(void **state)
{
    (void)state;
    static uint8_t staged_flash[FLASH_SIM_PAGES][HAL_FLASH_PAGE_BYTES];
    static uint8_t new_img[2200];
    small_app();
    for (uint16_t n = 0; n < BOOT_STARTS_MAX; n++)
        assert_true(boot_start(&w.hal, arm->model_number));
    assert_false(boot_start(&w.hal, arm->model_number));
    /* Stage and mark an image as a verified session does. */
    hal_host_image_build(new_img, sizeof new_img, arm->model_number, 5, 9);
    for (uint8_t p = 0; (uint32_t)p * HAL_FLASH_PAGE_BYTES < sizeof new_img; p++) {
        uint8_t page[HAL_FLASH_PAGE_BYTES];
        uint32_t at = (uint32_t)p * HAL_FLASH_PAGE_BYTES;
        memset(page, 0xFF, sizeof page);
        memcpy(page, &new_img[at],
               sizeof new_img - at < HAL_FLASH_PAGE_BYTES ? sizeof new_img - at : HAL_FLASH_PAGE_BYTES);
        assert_true(image_write_page(&w.hal, (uint8_t)(HAL_PAGE_STAGING + p), page,
                                     HAL_FLASH_PAGE_BYTES));
    }
    assert_true(hal_flash_program(&w.hal, IMAGE_MARK_PAGE, IMAGE_MARK_OFFSET, IMAGE_MARK_SET));
    memcpy(staged_flash, w.hal.flash.mem, sizeof staged_flash);
    w.hal.flash.ops = 0;
    assert_true(boot_start(&w.hal, arm->model_number));
    uint32_t total = w.hal.flash.ops;
    assert_int_equal(unconfirmed(), 1);
    for (uint8_t kind = FLASH_CUT_CLEAN; kind <= FLASH_CUT_TORN; kind++) {
        for (uint32_t k = 1; k <= total; k++) {
            memcpy(w.hal.flash.mem, staged_flash, sizeof staged_flash);
            flash_sim_power_on(&w.hal.flash);
            w.hal.flash.cut_kind = kind;
            w.hal.flash.cut_at = k;
            (void)boot_start(&w.hal, arm->model_number);
            assert_false(w.hal.flash.powered);
            flash_sim_power_on(&w.hal.flash);
            if (!boot_start(&w.hal, arm->model_number))
                fail_msg("cut at install operation %u (kind %u): still locked", k, kind);
            assert_true(unconfirmed() >= 1u && unconfirmed() <= 2u);
            assert_memory_equal(w.hal.flash.mem[HAL_PAGE_APP], new_img, HAL_FLASH_PAGE_BYTES);
        }
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_torn_marks_keep_their_kind),
        cmocka_unit_test(test_start_and_confirm_marks),
        cmocka_unit_test(test_good_image_confirms_at_first_answer),
        cmocka_unit_test(test_good_image_confirms_after_a_while),
        cmocka_unit_test(test_good_image_never_falls_back),
        cmocka_unit_test(test_hanging_image_leaves_update_mode_reachable),
        cmocka_unit_test(test_hanging_factory_image),
        cmocka_unit_test(test_short_power_ups_never_lock_a_good_image),
        cmocka_unit_test(test_tidy_waits_for_quiet),
        cmocka_unit_test(test_full_record),
        cmocka_unit_test(test_torn_erase_leftovers),
        cmocka_unit_test(test_power_cut_at_every_record_operation),
        cmocka_unit_test(test_cut_counts_at_most_one_start),
        cmocka_unit_test(test_install_empties_record_through_cuts),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
