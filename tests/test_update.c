/* test_update.c - firmware update over the bus (PROTOCOL.md §10): the session byte by
 * byte on a host servo, every refusal leaving the old firmware running, update mode when
 * the application is damaged, and a power cut at every flash operation of a session and
 * of the install after it (then a second cut during the re-install): the servo always
 * comes back running the old image or the new one, with its settings. */
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

/* ---- a servo on the bus ------------------------------------------------------------ */

/* Send and require exactly the status packet `D5 5D id LEN 00 data CHK`. */
static void expect_answer(const uint8_t *out, uint16_t n, uint8_t id, const uint8_t *data,
                          uint8_t dn)
{
    uint8_t ans[64], want[16];
    uint16_t wn = proto_build_packet(want, id, 0, data, dn);
    uint16_t got = wire_xfer(&w, out, n, ans);
    assert_int_equal(got, wn);
    assert_memory_equal(ans, want, wn);
}

static const uint8_t ACK[] = {UPDATE_ACK}, NAK[] = {UPDATE_NAK}, CAN[] = {UPDATE_CAN};
static const uint8_t ACK_C[] = {UPDATE_ACK, UPDATE_READY}, READY[] = {UPDATE_READY};

static uint8_t wire[WIRE_MAX];

static void send_enter(uint8_t id)
{
    expect_answer(wire, enter_frame(wire, id), id, READY, 1);
}

/* A whole good session of img to id, up to and including the end-of-batch ACK. */
static void send_image(uint8_t id, const uint8_t *img, uint32_t len)
{
    send_enter(id);
    expect_answer(wire, header_frame(wire, id, len), id, ACK_C, 2);
    for (uint8_t b = 1; b <= blocks_of(len); b++)
        expect_answer(wire, data_frame(wire, id, img, len, b), id, ACK, 1);
    expect_answer(wire, eof_frame(wire, id), id, ACK_C, 2);
    expect_answer(wire, batch_end_frame(wire, id), id, ACK, 1);
}

/* READ of n registers from addr; returns the answer's data via out. */
static void read_regs(uint8_t id, uint8_t addr, uint8_t n, uint8_t *out)
{
    uint8_t pkt[8], ans[64];
    const uint8_t params[2] = {addr, n};
    uint16_t len = proto_build_packet(pkt, id, INS_READ, params, 2);
    uint16_t got = wire_xfer(&w, pkt, len, ans);
    assert_int_equal(got, 6u + n);
    assert_int_equal(ans[4], 0); /* ERR */
    memcpy(out, &ans[5], n);
}

static uint8_t version_of(uint8_t id)
{
    uint8_t v;
    read_regs(id, REG_FIRMWARE_VERSION, 1, &v);
    return v;
}

static void write_reg(uint8_t id, uint8_t addr, uint8_t value)
{
    uint8_t pkt[8], ans[64];
    const uint8_t params[2] = {addr, value};
    uint16_t len = proto_build_packet(pkt, id, INS_WRITE, params, 2);
    (void)wire_xfer(&w, pkt, len, ans);
}

static bool pinged(uint8_t id)
{
    uint8_t pkt[8], ans[64];
    uint16_t len = proto_build_packet(pkt, id, INS_PING, 0, 0);
    return wire_xfer(&w, pkt, len, ans) == 7u;
}

static bool app_holds(const uint8_t *img, uint32_t len)
{
    for (uint32_t at = 0; at < len; at += HAL_FLASH_PAGE_BYTES) {
        uint32_t n = len - at < HAL_FLASH_PAGE_BYTES ? len - at : HAL_FLASH_PAGE_BYTES;
        if (memcmp(w.hal.flash.mem[HAL_PAGE_APP + at / HAL_FLASH_PAGE_BYTES], &img[at], n) != 0)
            return false;
    }
    return true;
}

#define IMG_LEN (16u * 1024u + 300u) /* 17 blocks, the last one padded */
static uint8_t img[IMAGE_MAX_BYTES + 1u];

/* A factory-fresh servo, img built (len bytes, model, version, seed), a session entered
 * and its header ACKed. */
static void begin_session(uint32_t len, uint16_t model, uint8_t version, uint32_t seed)
{
    wire_factory(&w);
    hal_host_image_build(img, len, model, version, seed);
    send_enter(1);
    expect_answer(wire, header_frame(wire, 1, len), 1, ACK_C, 2);
}

/* ---- tests ------------------------------------------------------------------------- */

static void test_crc_check_values(void **state)
{
    (void)state;
    const uint8_t text[] = "123456789";
    assert_int_equal(~crc32_update(CRC32_INIT, text, 9), 0xCBF43926u);
    assert_int_equal(crc16_update(0, text, 9), 0x31C3u);      /* XMODEM */
    assert_int_equal(crc16_update(0xFFFFu, text, 9), 0x29B1u); /* CCITT-FALSE */
}

/* The two update rows of VECTORS.md, byte for byte. */
static void test_vector_rows(void **state)
{
    (void)state;
    wire_factory(&w);
    uint8_t ans[64];
    static const uint8_t enter[] = {0xD5, 0x5D, 0x01, 0x03, 0xFF, 0xFC, 0xFF};
    static const uint8_t enter_ans[] = {0xD5, 0x5D, 0x01, 0x03, 0x00, 0x43, 0x47};
    assert_int_equal(wire_xfer(&w, enter, sizeof enter, ans), sizeof enter_ans);
    assert_memory_equal(ans, enter_ans, sizeof enter_ans);
    hal_host_image_build(img, 2000, arm->model_number, 2, 5);
    expect_answer(wire, header_frame(wire, 1, 2000), 1, ACK_C, 2);
    expect_answer(wire, data_frame(wire, 1, img, 2000, 1), 1, ACK, 1);
    expect_answer(wire, data_frame(wire, 1, img, 2000, 2), 1, ACK, 1);
    static const uint8_t eof[] = {0xD5, 0x5D, 0x01, 0x04, 0xFF, 0xFE, 0x04, 0x06};
    static const uint8_t eof_ans[] = {0xD5, 0x5D, 0x01, 0x04, 0x00, 0x06, 0x43, 0x4E};
    assert_int_equal(wire_xfer(&w, eof, sizeof eof, ans), sizeof eof_ans);
    assert_memory_equal(ans, eof_ans, sizeof eof_ans);
}

/* The whole session: the new image runs after the restart, the settings stay. */
static void test_session_installs_new_image(void **state)
{
    (void)state;
    wire_factory(&w);
    assert_int_equal(version_of(1), SERVO_FW_VERSION);
    write_reg(1, REG_RETURN_DELAY, 4); /* settings that must survive the update */
    write_reg(1, REG_ID, 7);
    hal_host_image_build(img, IMG_LEN, arm->model_number, 9, 1);
    send_image(7, img, IMG_LEN);
    wire_step(&w, 50000); /* the restart happens once the ACK is out */
    assert_false(loader_running(&w.s.loader));
    assert_true(app_holds(img, IMG_LEN));
    assert_true(pinged(7));
    assert_int_equal(version_of(7), 9);
    assert_int_equal(w.s.regs.mem[REG_RETURN_DELAY], 4);
    /* The staged copy is consumed: a later power cycle installs nothing. */
    uint32_t erases = w.hal.flash.erases[HAL_PAGE_APP];
    wire_power_on(&w);
    assert_int_equal(w.hal.flash.erases[HAL_PAGE_APP], erases);
    assert_int_equal(version_of(7), 9);
}

/* Status return level 0 answers nothing else, but the update still gets its answers. */
static void test_answered_whatever_status_level(void **state)
{
    (void)state;
    wire_factory(&w);
    write_reg(1, REG_STATUS_RETURN_LEVEL, 0);
    uint8_t ans[64];
    const uint8_t params[2] = {REG_ID, 1};
    uint16_t n = proto_build_packet(wire, 1, INS_READ, params, 2);
    assert_int_equal(wire_xfer(&w, wire, n, ans), 0);
    send_enter(1);
}

/* Damaged blocks are NAKed and taken when resent; a repeated block is ACKed again and
 * not written twice. */
static void test_nak_resend_and_repeat(void **state)
{
    (void)state;
    begin_session(3000, arm->model_number, 3, 2);
    uint16_t n = data_frame(wire, 1, img, 3000, 1);
    wire[100] ^= 0x10u; /* a data byte: CRC-16 and checksum both wrong */
    expect_answer(wire, n, 1, NAK, 1);
    n = data_frame(wire, 1, img, 3000, 1);
    wire[n - 2u] ^= 0x01u; /* CRC-16 low byte */
    wire[n - 1u] ^= 0x01u; /* checksum kept right: only the CRC tells */
    expect_answer(wire, n, 1, NAK, 1);
    n = data_frame(wire, 1, img, 3000, 1);
    wire[n - 1u] ^= 0x80u; /* checksum only */
    expect_answer(wire, n, 1, NAK, 1);
    expect_answer(wire, data_frame(wire, 1, img, 3000, 3), 1, NAK, 1); /* 1 expected */
    n = data_frame(wire, 1, img, 3000, 1);
    wire[9] ^= 0x01u; /* ~n no longer the complement */
    wire[n - 1u] ^= 0x01u;
    expect_answer(wire, n, 1, NAK, 1);
    expect_answer(wire, data_frame(wire, 1, img, 3000, 1), 1, ACK, 1);
    uint32_t erases = w.hal.flash.erases[HAL_PAGE_STAGING];
    expect_answer(wire, data_frame(wire, 1, img, 3000, 1), 1, ACK, 1); /* repeated */
    assert_int_equal(w.hal.flash.erases[HAL_PAGE_STAGING], erases);
    expect_answer(wire, data_frame(wire, 1, img, 3000, 2), 1, ACK, 1);
    expect_answer(wire, data_frame(wire, 1, img, 3000, 3), 1, ACK, 1);
    expect_answer(wire, eof_frame(wire, 1), 1, ACK_C, 2);
    expect_answer(wire, eof_frame(wire, 1), 1, ACK_C, 2); /* EOF's ACK lost: again */
    expect_answer(wire, batch_end_frame(wire, 1), 1, ACK, 1);
    wire_step(&w, 50000);
    assert_int_equal(version_of(1), 3);
    /* The host missed the last ACK and resends the end of batch to the new firmware. */
    expect_answer(wire, batch_end_frame(wire, 1), 1, ACK, 1);
}

/* After a refusal the old firmware keeps running, untouched, also after a restart. */
static void assert_old_firmware_runs(void)
{
    static uint8_t factory_img[HAL_HOST_FACTORY_BYTES];
    hal_host_image_build(factory_img, sizeof factory_img, arm->model_number, SERVO_FW_VERSION, 1);
    assert_true(pinged(1));
    assert_int_equal(version_of(1), SERVO_FW_VERSION);
    wire_power_on(&w);
    assert_false(loader_running(&w.s.loader));
    assert_true(app_holds(factory_img, sizeof factory_img));
    assert_int_equal(version_of(1), SERVO_FW_VERSION);
}

static void test_refuses_too_large(void **state)
{
    (void)state;
    wire_factory(&w);
    send_enter(1);
    expect_answer(wire, header_frame(wire, 1, IMAGE_MAX_BYTES + 1u), 1, CAN, 1);
    expect_answer(wire, data_frame(wire, 1, img, 2000, 1), 1, CAN, 1); /* session over */
    assert_old_firmware_runs();
    /* An image that claims a fitting length but sends more blocks than that. */
    hal_host_image_build(img, 1500, arm->model_number, 4, 3);
    send_enter(1);
    expect_answer(wire, header_frame(wire, 1, 1500), 1, ACK_C, 2);
    expect_answer(wire, data_frame(wire, 1, img, 1500, 1), 1, ACK, 1);
    expect_answer(wire, data_frame(wire, 1, img, 1500, 2), 1, ACK, 1);
    expect_answer(wire, data_frame(wire, 1, img, 3000, 3), 1, CAN, 1);
    assert_old_firmware_runs();
}

static void test_refuses_wrong_board(void **state)
{
    (void)state;
    begin_session(3000, board_wrist.model_number, 4, 3);
    expect_answer(wire, data_frame(wire, 1, img, 3000, 1), 1, CAN, 1);
    assert_old_firmware_runs();
    /* The header's length and the image's own disagree. */
    hal_host_image_build(img, 3000, arm->model_number, 4, 3);
    send_enter(1);
    expect_answer(wire, header_frame(wire, 1, 2900), 1, ACK_C, 2);
    expect_answer(wire, data_frame(wire, 1, img, 3000, 1), 1, CAN, 1);
    assert_old_firmware_runs();
}

static void test_refuses_bad_crc(void **state)
{
    (void)state;
    begin_session(3000, arm->model_number, 4, 3);
    img[2500] ^= 0x04u; /* arrives intact (block CRCs of these bytes), fails CRC-32 */
    for (uint8_t b = 1; b <= 3u; b++)
        expect_answer(wire, data_frame(wire, 1, img, 3000, b), 1, ACK, 1);
    expect_answer(wire, eof_frame(wire, 1), 1, ACK_C, 2);
    expect_answer(wire, batch_end_frame(wire, 1), 1, CAN, 1);
    assert_old_firmware_runs();
}

static void test_refuses_truncated(void **state)
{
    (void)state;
    begin_session(3000, arm->model_number, 4, 3);
    expect_answer(wire, data_frame(wire, 1, img, 3000, 1), 1, ACK, 1);
    expect_answer(wire, data_frame(wire, 1, img, 3000, 2), 1, ACK, 1);
    expect_answer(wire, eof_frame(wire, 1), 1, CAN, 1);
    assert_old_firmware_runs();
    /* A frame out of order: a data block or end of file before any header. */
    send_enter(1);
    expect_answer(wire, data_frame(wire, 1, img, 3000, 1), 1, CAN, 1);
    send_enter(1);
    expect_answer(wire, eof_frame(wire, 1), 1, CAN, 1);
    expect_answer(wire, header_frame(wire, 1, 3000), 1, CAN, 1); /* no session */
    assert_old_firmware_runs();
}

/* A full-length image padded with zeros (as YMODEM senders may pad): its last data block
 * covers the install mark's half-word. The padding is not written, so a session
 * abandoned after that block installs nothing (fuzz_update found it installed). */
static void test_padding_never_sets_the_install_mark(void **state)
{
    (void)state;
    begin_session(IMAGE_MAX_BYTES, arm->model_number, 6, 11);
    uint8_t d[PROTO_UPDATE_BLOCK_DATA];
    for (uint8_t num = 1; num <= blocks_of(IMAGE_MAX_BYTES); num++) {
        uint32_t at = (uint32_t)(num - 1u) * PROTO_UPDATE_BLOCK_DATA;
        uint32_t n = IMAGE_MAX_BYTES - at < sizeof d ? IMAGE_MAX_BYTES - at : sizeof d;
        memset(d, 0x00, sizeof d); /* zero padding */
        memcpy(d, &img[at], n);
        expect_answer(wire, block_frame(wire, 1, PROTO_UPDATE_TYPE_DATA, num, d), 1, ACK, 1);
    }
    assert_false(image_marked(&w.hal)); /* every block in, nothing verified yet */
    wire_step(&w, UPDATE_TIMEOUT_US + 100000u); /* the host walks away */
    assert_false(image_marked(&w.hal));
    assert_old_firmware_runs(); /* and the power cycle in it installs nothing */
}

/* Other IDs and the broadcast ID never start a session or get an answer. */
static void test_other_ids_ignored(void **state)
{
    (void)state;
    wire_factory(&w);
    uint8_t ans[64];
    assert_int_equal(wire_xfer(&w, wire, enter_frame(wire, 2), ans), 0);
    assert_int_equal(wire_xfer(&w, wire, enter_frame(wire, PROTO_ID_BROADCAST), ans), 0);
    assert_int_equal(w.s.update.state, UPDATE_IDLE);
}

/* No motion during an update: FC turns the torque off, motion commands are refused
 * until the session ends; a silent session ends after UPDATE_TIMEOUT_US. */
static void test_motor_off_during_session(void **state)
{
    (void)state;
    hal_host_init(&w.hal);
    hal_host_attach_board(&w.hal, &board_base);
    hal_host_program_factory(&w.hal, &board_base);
    hal_host_reboot(&w.hal);
    servo_power_on(&w.s, &board_base, &w.hal);
    write_reg(1, REG_HEARTBEAT_ENABLE, 0);
    uint8_t ans[64];
    const uint8_t speed[3] = {REG_MOVING_SPEED, 100, 0};
    uint16_t n = proto_build_packet(wire, 1, INS_WRITE, speed, 3);
    (void)wire_xfer(&w, wire, n, ans);
    wire_step(&w, 200000);
    assert_true(w.hal.motor.enabled);
    assert_int_not_equal(w.hal.motor.duty, 0);
    expect_answer(wire, enter_frame(wire, 1), 1, READY, 1);
    assert_false(w.hal.motor.enabled);
    assert_int_equal(w.hal.motor.duty, 0);
    n = proto_build_packet(wire, 1, INS_WRITE, speed, 3);
    assert_int_equal(wire_xfer(&w, wire, n, ans), 6);
    assert_int_equal(ans[4], ERR_INSTRUCTION);
    wire_step(&w, 500000);
    assert_false(w.hal.motor.enabled);
    assert_true(pinged(1));
    for (uint32_t t = 0; t < UPDATE_TIMEOUT_US; t += 10000u)
        wire_step(&w, 10000);
    assert_false(w.hal.motor.enabled); /* the end of a session moves nothing by itself */
    n = proto_build_packet(wire, 1, INS_WRITE, speed, 3);
    assert_int_equal(wire_xfer(&w, wire, n, ans), 6);
    assert_int_equal(ans[4] & ERR_INSTRUCTION, 0);
    wire_step(&w, 200000);
    assert_true(w.hal.motor.enabled);
}

/* A damaged application: the bootloader stays in update mode at the stored ID and baud,
 * answers only §10, and an update brings the servo back. */
static void test_update_mode_when_application_damaged(void **state)
{
    (void)state;
    wire_factory(&w);
    write_reg(1, REG_ID, 9);
    w.hal.flash.mem[HAL_PAGE_APP + 3u][17] ^= 0x20u;
    wire_power_on(&w);
    assert_true(loader_running(&w.s.loader));
    assert_false(pinged(9));
    uint8_t ans[64];
    const uint8_t params[2] = {REG_ID, 1};
    uint16_t n = proto_build_packet(wire, 9, INS_READ, params, 2);
    assert_int_equal(wire_xfer(&w, wire, n, ans), 0);
    assert_int_equal(wire_xfer(&w, wire, enter_frame(wire, 1), ans), 0); /* not its ID */
    hal_host_image_build(img, IMG_LEN, arm->model_number, 6, 8);
    send_image(9, img, IMG_LEN);
    wire_step(&w, 50000);
    assert_false(loader_running(&w.s.loader));
    assert_true(pinged(9));
    assert_int_equal(version_of(9), 6);
}

/* The receiver: the §10 data block is the only frame longer than its LEN says. */
static void test_receiver_oversize_only_for_data_blocks(void **state)
{
    (void)state;
    struct frame_rx *rx = &w.s.rx;
    uint32_t now = 0;
    frame_rx_init(rx, 9600);
    hal_host_image_build(img, 2000, arm->model_number, 2, 5);
    uint16_t n = data_frame(wire, 1, img, 2000, 1);
    for (uint16_t i = 0; i < n; i++)
        frame_rx_byte(rx, wire[i], now += WIRE_BYTE_US);
    const struct frame *b = frame_rx_peek(rx);
    assert_non_null(b);
    assert_ptr_equal(b->buf, rx->buf); /* all the slots, from the first */
    assert_int_equal(b->len, FRAME_BLOCK_BYTES);
    assert_int_equal(b->status, FRAME_OK);
    assert_memory_equal(b->buf, &wire[2], FRAME_BLOCK_BYTES);
    frame_rx_release(rx);
    /* LEN 0xFF, INS 0xFF, sub 0xFE, but type 1: an ordinary 257-byte frame, after which
     * the rest of the bytes are not a frame. */
    wire[6] = PROTO_UPDATE_TYPE_HEADER;
    for (uint16_t i = 0; i < n; i++)
        frame_rx_byte(rx, wire[i], now += WIRE_BYTE_US);
    const struct frame *f = frame_rx_peek(rx);
    assert_non_null(f);
    assert_int_equal(f->len, FRAME_BYTES);
    frame_rx_release(rx);
    /* A WRITE with LEN 0xFF keeps its length too (after the line has rested, so the
     * rest of the bytes above is forgotten). */
    now += 10000u;
    assert_true(frame_rx_idle(rx, now));
    while (frame_rx_peek(rx))
        frame_rx_release(rx);
    uint8_t params[253] = {REG_GOAL_POSITION};
    n = proto_build_packet(wire, 1, INS_WRITE, params, sizeof params);
    for (uint16_t i = 0; i < n; i++)
        frame_rx_byte(rx, wire[i], now += WIRE_BYTE_US);
    f = frame_rx_peek(rx);
    assert_non_null(f);
    assert_int_equal(f->len, FRAME_BYTES);
    assert_int_equal(f->status, FRAME_OK);
}

/* ---- power cuts -------------------------------------------------------------------- */

/* A session run straight through update_frame() (no bus: the flash operations are the
 * same, and thousands of sessions stay fast). Returns true when it ended verified. */
static bool session_direct(const uint8_t *im, uint32_t len)
{
    struct update u = {0};
    uint8_t ans[2], n;
    static uint8_t fr[WIRE_MAX];
    uint16_t fn = enter_frame(fr, 1);
    (void)update_frame(&u, &w.hal, arm->model_number, &fr[2], (uint16_t)(fn - 2u), true, 0, ans, &n);
    fn = header_frame(fr, 1, len);
    (void)update_frame(&u, &w.hal, arm->model_number, &fr[2], (uint16_t)(fn - 2u), true, 0, ans, &n);
    for (uint8_t b = 1; b <= blocks_of(len); b++) {
        fn = data_frame(fr, 1, im, len, b);
        (void)update_frame(&u, &w.hal, arm->model_number, &fr[2], (uint16_t)(fn - 2u), true, 0,
                           ans, &n);
        if (ans[0] != UPDATE_ACK)
            return false;
    }
    fn = eof_frame(fr, 1);
    (void)update_frame(&u, &w.hal, arm->model_number, &fr[2], (uint16_t)(fn - 2u), true, 0, ans, &n);
    fn = batch_end_frame(fr, 1);
    return update_frame(&u, &w.hal, arm->model_number, &fr[2], (uint16_t)(fn - 2u), true, 0, ans,
                        &n) == UPDATE_RESTART;
}

#define CUT_LEN 2200u /* 3 blocks: ~1,100 program/erase operations per session */
static uint8_t old_img[CUT_LEN], new_img[CUT_LEN];
static uint8_t before[FLASH_SIM_PAGES][HAL_FLASH_PAGE_BYTES];

/* Power comes back (the cut cleared) and the bootloader decides. */
static bool cut_boot(void)
{
    flash_sim_power_on(&w.hal.flash);
    return boot_install(&w.hal, arm->model_number);
}

/* What must hold after any cut, once the power is back: a valid application that is
 * the old image or the new one, and the store pages as they were. */
static void assert_boots_old_or_new(uint32_t cut)
{
    bool ok = cut_boot();
    if (!ok || !(app_holds(old_img, CUT_LEN) || app_holds(new_img, CUT_LEN)))
        fail_msg("cut at operation %u: the servo does not boot the old or the new image", cut);
    assert_memory_equal(w.hal.flash.mem, before, HAL_FLASH_PAGES * HAL_FLASH_PAGE_BYTES);
}

static void cut_setup(void)
{
    hal_host_init(&w.hal);
    hal_host_image_build(old_img, CUT_LEN, arm->model_number, 1, 11);
    hal_host_image_build(new_img, CUT_LEN, arm->model_number, 2, 12);
    hal_host_program_app(&w.hal, old_img, CUT_LEN);
    for (uint16_t off = 0; off < 64u; off += 2u) /* something in the store pages */
        (void)hal_flash_program(&w.hal, 1, off, (uint16_t)(0x1234u + off));
    /* An earlier update left its install mark (its staged copy is consumed): the
     * session must clear the mark first, and that erase is cut too. */
    (void)hal_flash_program(&w.hal, IMAGE_MARK_PAGE, IMAGE_MARK_OFFSET, IMAGE_MARK_SET);
    memcpy(before, w.hal.flash.mem, sizeof before);
}

/* Every operation of a session, then of the install at the next boot, interrupted in
 * each of the three ways (not done, done, torn). */
static void test_power_cut_at_every_flash_operation(void **state)
{
    (void)state;
    cut_setup();
    w.hal.flash.ops = 0;
    assert_true(session_direct(new_img, CUT_LEN));
    uint32_t session_ops = w.hal.flash.ops;
    w.hal.flash.ops = 0;
    assert_true(cut_boot());
    uint32_t install_ops = w.hal.flash.ops;
    assert_true(app_holds(new_img, CUT_LEN));
    assert_true(session_ops > 1000u && install_ops > 1000u);

    uint32_t scenarios = 0;
    for (uint8_t kind = FLASH_CUT_CLEAN; kind <= FLASH_CUT_TORN; kind++) {
        for (uint32_t k = 1; k <= session_ops + install_ops; k++) {
            memcpy(w.hal.flash.mem, before, sizeof before);
            flash_sim_power_on(&w.hal.flash);
            w.hal.flash.cut_kind = kind;
            if (k <= session_ops) {
                w.hal.flash.cut_at = k;
                assert_false(session_direct(new_img, CUT_LEN));
            } else {
                assert_true(session_direct(new_img, CUT_LEN));
                flash_sim_power_on(&w.hal.flash); /* the restart after the verified session */
                w.hal.flash.cut_kind = kind;
                w.hal.flash.cut_at = k - session_ops;
                (void)boot_install(&w.hal, arm->model_number);
            }
            assert_false(w.hal.flash.powered);
            assert_boots_old_or_new(k);
            /* A cut in the install is finished by the boot after it. */
            if (k > session_ops)
                assert_true(app_holds(new_img, CUT_LEN));
            /* And the servo stays updatable: a whole session now succeeds. */
            if (k % 97u == 0u) {
                assert_true(session_direct(new_img, CUT_LEN));
                assert_true(cut_boot());
                assert_true(app_holds(new_img, CUT_LEN));
            }
            scenarios++;
        }
    }
    print_message("power cuts: %u scenarios (%u session + %u install operations x 3)\n",
                  scenarios, session_ops, install_ops);
}

/* A cut in the install, then another at every operation of the install that redoes it. */
static void test_second_cut_during_reinstall(void **state)
{
    (void)state;
    cut_setup();
    assert_true(session_direct(new_img, CUT_LEN));
    memcpy(before, w.hal.flash.mem, sizeof before); /* staged, not installed */
    flash_sim_power_on(&w.hal.flash);
    assert_true(boot_install(&w.hal, arm->model_number));
    uint32_t install_ops = w.hal.flash.ops;
    for (uint32_t first = 1; first <= install_ops; first += 173u) {
        for (uint32_t second = 1; second <= install_ops; second += 3u) {
            memcpy(w.hal.flash.mem, before, sizeof before);
            flash_sim_power_on(&w.hal.flash);
            w.hal.flash.cut_kind = FLASH_CUT_TORN;
            w.hal.flash.cut_at = first;
            (void)boot_install(&w.hal, arm->model_number);
            flash_sim_power_on(&w.hal.flash);
            w.hal.flash.cut_kind = (uint8_t)(second % 3u);
            w.hal.flash.cut_at = second;
            (void)boot_install(&w.hal, arm->model_number);
            if (!cut_boot() || !app_holds(new_img, CUT_LEN))
                fail_msg("cuts at install operations %u then %u: new image not installed",
                         first, second);
        }
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc_check_values),
        cmocka_unit_test(test_vector_rows),
        cmocka_unit_test(test_session_installs_new_image),
        cmocka_unit_test(test_answered_whatever_status_level),
        cmocka_unit_test(test_nak_resend_and_repeat),
        cmocka_unit_test(test_refuses_too_large),
        cmocka_unit_test(test_refuses_wrong_board),
        cmocka_unit_test(test_refuses_bad_crc),
        cmocka_unit_test(test_refuses_truncated),
        cmocka_unit_test(test_padding_never_sets_the_install_mark),
        cmocka_unit_test(test_other_ids_ignored),
        cmocka_unit_test(test_motor_off_during_session),
        cmocka_unit_test(test_update_mode_when_application_damaged),
        cmocka_unit_test(test_receiver_oversize_only_for_data_blocks),
        cmocka_unit_test(test_power_cut_at_every_flash_operation),
        cmocka_unit_test(test_second_cut_during_reinstall),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
