/* test_dispatch.c - instruction execution and answers (PROTOCOL.md §3-§5): a real servo on
 * the host HAL, driven through its UART interrupt and main loop (and, where a hand-built
 * frame says it better, through dispatch_frame() directly).
 *
 * The motion layer (command.h, motion.h) and safety are replaced by a small hand-written
 * fake (below) whose motor never moves, which accepts motion commands and records what the
 * dispatcher decoded, so that START/END and CUSTOM decoding can be checked. The test links the bus side of the
 * core only (tests/CMakeLists.txt), so the fake is the one motion layer in the program. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "command.h"
#include "dispatch.h"
#include "hal_host.h"
#include "motion.h"
#include "proto.h"
#include "servo.h"

/* ---- fake motion layer --------------------------------------------------------- */

static struct {
    uint8_t result; /* what motion commands return */
    uint32_t custom_calls;
    struct custom_move custom;
    uint32_t start_end_calls;
    uint8_t start_end_what;
    uint32_t traj_action_calls;
    uint32_t reset_calls;
    uint32_t torque_off_calls;
    uint8_t live_err; /* what the safety layer reports */
} fake;

void motion_poll(struct servo *s, uint32_t now_us)
{
    (void)s;
    (void)now_us;
}

void safety_packet_seen(struct safety *sf)
{
    (void)sf;
}

uint8_t safety_err(const struct safety *sf)
{
    (void)sf;
    return fake.live_err;
}

void motion_report(struct servo *s)
{
    (void)s;
}

void motion_init(struct servo *s)
{
    regs_set(&s->regs, REG_GOAL_POSITION, regs_present_position(&s->regs));
}

uint8_t command_write_check(const struct servo *s, const struct reg_write *w)
{
    (void)s;
    (void)w;
    return 0;
}

void command_written(struct servo *s, const struct reg_write *w)
{
    (void)s;
    (void)w;
}

bool command_may_move(const struct servo *s)
{
    (void)s;
    return fake.result == 0u;
}

uint8_t command_start_end(struct servo *s, uint8_t what)
{
    (void)s;
    fake.start_end_calls++;
    fake.start_end_what = what;
    return fake.result;
}

void command_traj_action(struct servo *s)
{
    (void)s;
    fake.traj_action_calls++;
}

void command_traj_written(struct servo *s)
{
    (void)s;
}

void command_custom_move(struct servo *s, const struct custom_move *m)
{
    (void)s;
    fake.custom_calls++;
    fake.custom = *m;
}

void command_reset(struct servo *s)
{
    (void)s;
    fake.reset_calls++;
}

void command_coast(struct servo *s)
{
    (void)s;
    fake.torque_off_calls++;
}

bool safety_may_clear(const struct safety *sf)
{
    (void)sf;
    return true;
}

void safety_clear(struct safety *sf)
{
    (void)sf;
}

/* ---- harness -------------------------------------------------------------------- */

static struct hal hal;
static struct servo s;

struct answer {
    uint8_t b[PROTO_STATUS_MAX + 8];
    uint32_t n;
    uint32_t baud;
};

static void power_up(const struct board *b)
{
    memset(&fake, 0, sizeof fake);
    hal_host_init(&hal);
    hal.now_us = 1000000u;
    servo_init(&s, b, &hal);
}

static int setup_foot(void **state)
{
    (void)state;
    power_up(&board_foot);
    return 0;
}

/* The host sends p at the servo's current baud; the servo runs until it has nothing left
 * to do (answer sent, queue empty). Returns what it put on the wire. */
static struct answer xfer(const uint8_t *p, size_t n)
{
    uint32_t baud = s.link.baud;
    hal.now_us += 5000u; /* the line was quiet */
    uint32_t t0 = hal.now_us;
    uint32_t first = hal.log_len;
    for (size_t i = 0; i < n; i++) {
        hal.now_us = hal_host_byte_end(t0, baud, (uint32_t)i);
        servo_rx_isr(&s, p[i]);
        servo_poll(&s);
    }
    uint32_t limit = hal.now_us + 5000000u;
    while (s.link.state != LINK_IDLE || frame_rx_peek(&s.rx) != 0 ||
           !frame_rx_idle(&s.rx, hal.now_us)) {
        assert_true((int32_t)(limit - hal.now_us) > 0);
        hal.now_us += 10u;
        servo_poll(&s);
    }
    struct answer a = {{0}, 0, 0};
    assert_true(hal.log_len - first <= sizeof a.b);
    for (uint32_t i = first; i < hal.log_len; i++) {
        a.b[a.n++] = hal_host_tx(&hal, i)->byte;
        a.baud = hal_host_tx(&hal, i)->baud;
    }
    return a;
}

/* Build D5 5D id LEN ins params CHK and send it. */
static struct answer cmd(uint8_t id, uint8_t ins, const uint8_t *params, size_t n)
{
    uint8_t p[262];
    return xfer(p, proto_build_packet(p, id, ins, params, (uint8_t)n));
}

static void assert_answer(struct answer a, const uint8_t *want, size_t n)
{
    if (a.n != n)
        fail_msg("answer of %u bytes, expected %zu", a.n, n);
    assert_memory_equal(a.b, want, n);
}

/* A status packet with no parameters from id with err. */
static void assert_status(struct answer a, uint8_t id, uint8_t err)
{
    uint8_t want[6] = {0xD5, 0x5D, id, 0x02, err, 0};
    want[5] = proto_sum(&want[2], 3);
    assert_answer(a, want, sizeof want);
}

static void assert_silent(struct answer a)
{
    if (a.n != 0)
        fail_msg("expected no answer, got %u bytes (ERR %02X)", a.n, a.b[4]);
}

static struct answer write1(uint8_t id, uint8_t addr, uint8_t v)
{
    const uint8_t p[] = {addr, v};
    return cmd(id, INS_WRITE, p, 2);
}

static struct answer write2(uint8_t id, uint8_t addr, uint16_t v)
{
    const uint8_t p[] = {addr, (uint8_t)v, (uint8_t)(v >> 8)};
    return cmd(id, INS_WRITE, p, 3);
}

static struct answer read_cmd(uint8_t id, uint8_t addr, uint8_t count)
{
    const uint8_t p[] = {addr, count};
    return cmd(id, INS_READ, p, 2);
}

static void set_reg(uint8_t addr, uint16_t v)
{
    struct answer a = regs_table[addr].size == 2 ? write2(1, addr, v) : write1(1, addr, (uint8_t)v);
    assert_status(a, 1, 0x00);
}

/* ---- PING (§4.1) ---------------------------------------------------------------- */

static void ping_answer_format(void **state)
{
    (void)state;
    const uint8_t want[] = {0xD5, 0x5D, 0x01, 0x03, 0x01, 0x00, 0x05};
    assert_answer(cmd(1, INS_PING, 0, 0), want, sizeof want);
    /* The ERR byte after 0x01 shows the live condition. */
    fake.live_err = ERR_OVER_TEMPERATURE;
    const uint8_t hot[] = {0xD5, 0x5D, 0x01, 0x03, 0x01, 0x01, 0x06};
    assert_answer(cmd(1, INS_PING, 0, 0), hot, sizeof hot);
}

static void ping_answered_at_every_level(void **state)
{
    (void)state;
    const uint8_t want[] = {0xD5, 0x5D, 0x01, 0x03, 0x01, 0x00, 0x05};
    for (uint8_t level = 0; level <= 2; level++) {
        power_up(&board_foot);
        set_reg(REG_STATUS_RETURN_LEVEL, level);
        assert_answer(cmd(1, INS_PING, 0, 0), want, sizeof want);
    }
}

static void broadcast_ping_answered_with_own_id(void **state)
{
    (void)state;
    set_reg(REG_ID, 9);
    const uint8_t want[] = {0xD5, 0x5D, 0x09, 0x03, 0x01, 0x00, 0x0D};
    assert_answer(cmd(PROTO_ID_BROADCAST, INS_PING, 0, 0), want, sizeof want);
}

static void ping_with_parameters_refused(void **state)
{
    (void)state;
    const uint8_t p[] = {0x00};
    assert_status(cmd(1, INS_PING, p, 1), 1, ERR_INSTRUCTION);
}

/* ---- READ (§4.2) ---------------------------------------------------------------- */

static void read_answers(void **state)
{
    (void)state;
    const uint8_t id[] = {0xD5, 0x5D, 0x01, 0x03, 0x00, 0x01, 0x05};
    assert_answer(read_cmd(1, REG_ID, 1), id, sizeof id);
    const uint8_t two[] = {0xD5, 0x5D, 0x01, 0x04, 0x00, 0x02, 0x01, 0x08};
    assert_answer(read_cmd(1, REG_STATUS_RETURN_LEVEL, 2), two, sizeof two);
    struct answer a = read_cmd(1, REG_MODEL_NUMBER, 2); /* little-endian */
    assert_int_equal(a.n, 8);
    assert_int_equal(a.b[5], 0x02);
    assert_int_equal(a.b[6], 0x52);
    /* The whole table in one READ. */
    a = read_cmd(1, 0, REGS_SIZE);
    assert_int_equal(a.n, 6u + REGS_SIZE);
    assert_int_equal(a.b[3], REGS_SIZE + 2u);
    assert_int_equal(a.b[4], 0x00);
    uint8_t table[REGS_SIZE];
    regs_read(&s.regs, 0, REGS_SIZE, table);
    assert_memory_equal(&a.b[5], table, REGS_SIZE);
    assert_int_equal(a.b[5 + REG_CCW_LIMIT], 360 & 0xFF);
    assert_int_equal(a.b[6 + REG_CCW_LIMIT], 360 >> 8);
    assert_int_equal(a.b[a.n - 1u], proto_sum(&a.b[2], (uint16_t)(a.n - 3u)));
    /* The last byte of the table. */
    a = read_cmd(1, REGS_SIZE - 1u, 1);
    assert_int_equal(a.n, 7);
}

static void read_hidden_addresses_as_zero(void **state)
{
    (void)state;
    s.regs.mem[10] = 0x77;                     /* reserved */
    s.regs.mem[REG_CLEAR_UNLOAD] = 0x77;       /* write-only */
    s.regs.mem[REG_PRESENT_POSITION] = 0x77;   /* not on the foot */
    s.regs.mem[REG_BASE_ACCELERATION] = 0x77;  /* base only */
    struct answer a = read_cmd(1, 0, REGS_SIZE);
    assert_int_equal(a.n, 6u + REGS_SIZE);
    assert_int_equal(a.b[5 + 10], 0);
    assert_int_equal(a.b[5 + REG_CLEAR_UNLOAD], 0);
    assert_int_equal(a.b[5 + REG_PRESENT_POSITION], 0);
    assert_int_equal(a.b[5 + REG_BASE_ACCELERATION], 0);
    assert_int_equal(a.b[5 + REG_ACCELERATION], 36);
}

static void read_errors(void **state)
{
    (void)state;
    assert_status(read_cmd(1, REG_ID, 0), 1, ERR_INSTRUCTION);         /* count 0 */
    assert_status(read_cmd(1, 48, 5), 1, ERR_INSTRUCTION);             /* past the end */
    assert_status(read_cmd(1, 0, REGS_SIZE + 1u), 1, ERR_INSTRUCTION);
    assert_status(read_cmd(1, REGS_SIZE, 1), 1, ERR_INSTRUCTION);
    assert_status(read_cmd(1, 0xFF, 0xFF), 1, ERR_INSTRUCTION);
    const uint8_t one[] = {REG_ID};
    assert_status(cmd(1, INS_READ, one, 1), 1, ERR_INSTRUCTION);
    const uint8_t three[] = {REG_ID, 1, 1};
    assert_status(cmd(1, INS_READ, three, 3), 1, ERR_INSTRUCTION);
    /* VECTORS.md, verbatim. */
    const uint8_t past[] = {0xD5, 0x5D, 0x01, 0x04, 0x02, 0x30, 0x05, 0x3C};
    const uint8_t err[] = {0xD5, 0x5D, 0x01, 0x02, 0x20, 0x23};
    assert_answer(xfer(past, sizeof past), err, sizeof err);
}

/* ---- WRITE (§4.3) --------------------------------------------------------------- */

static void write_applies_and_answers(void **state)
{
    (void)state;
    const uint8_t pkt[] = {0xD5, 0x5D, 0x01, 0x04, 0x03, 0x05, 0x00, 0x0D}; /* delay := 0 */
    const uint8_t ok[] = {0xD5, 0x5D, 0x01, 0x02, 0x00, 0x03};
    assert_answer(xfer(pkt, sizeof pkt), ok, sizeof ok);
    assert_int_equal(s.regs.mem[REG_RETURN_DELAY], 0);
    /* Several registers at once, 16-bit little-endian. */
    const uint8_t gs[] = {REG_GOAL_POSITION, 0x2C, 0x01, 0x64, 0x80};
    assert_status(cmd(1, INS_WRITE, gs, sizeof gs), 1, 0x00);
    assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), 300);
    assert_int_equal(regs_get(&s.regs, REG_MOVING_SPEED), 0x8064);
}

/* A write that is refused leaves the whole table as it was. */
static void assert_write_refused(const uint8_t *p, size_t n)
{
    uint8_t before[REGS_SIZE];
    memcpy(before, s.regs.mem, REGS_SIZE);
    assert_status(cmd(1, INS_WRITE, p, n), 1, ERR_INSTRUCTION);
    assert_memory_equal(s.regs.mem, before, REGS_SIZE);
}

static void write_all_or_nothing(void **state)
{
    (void)state;
    const uint8_t bad_baud[] = {REG_ID, 5, 11, 0};        /* 3, 4 (11: no such code), 5 */
    assert_write_refused(bad_baud, sizeof bad_baud);
    const uint8_t bad_id[] = {REG_ID, 254};
    assert_write_refused(bad_id, sizeof bad_id);
    const uint8_t ro[] = {41, 0, 0, 0};                  /* 41 is a high byte, 42 R */
    assert_write_refused(ro, sizeof ro);
    const uint8_t ro2[] = {REG_BRAKE, 1, 1};             /* 43 ok, 44 read-only */
    assert_write_refused(ro2, sizeof ro2);
    const uint8_t rsv[] = {10, 0, 80};                   /* 10 reserved, 11 */
    assert_write_refused(rsv, sizeof rsv);
    const uint8_t rsv2[] = {REG_RESOLUTION, 10, 0};      /* 13, 14 reserved */
    assert_write_refused(rsv2, sizeof rsv2);
    const uint8_t na[] = {REG_BASE_ACCELERATION, 10};     /* base only */
    assert_write_refused(na, sizeof na);
    const uint8_t half[] = {REG_GOAL_POSITION, 0x10};     /* half a register */
    assert_write_refused(half, sizeof half);
    const uint8_t high[] = {REG_GOAL_POSITION + 1u, 0x10};
    assert_write_refused(high, sizeof high);
    const uint8_t half_speed[] = {REG_GOAL_POSITION, 0x10, 0x00, 0x05};
    assert_write_refused(half_speed, sizeof half_speed);
    const uint8_t past[] = {REG_MOVE_WITHOUT_REFERENCE, 1, 1};
    assert_write_refused(past, sizeof past);
    const uint8_t outside[] = {REGS_SIZE, 1};
    assert_write_refused(outside, sizeof outside);
    const uint8_t no_data[] = {REG_ID};
    assert_write_refused(no_data, sizeof no_data);
    assert_write_refused(no_data, 0);
    const uint8_t cw_over[] = {REG_CW_LIMIT, 0x69, 0x01};  /* 361 > CCW 360 */
    assert_write_refused(cw_over, sizeof cw_over);
    const uint8_t cross[] = {REG_CW_LIMIT, 100, 0, 50, 0};
    assert_write_refused(cross, sizeof cross);
    const uint8_t zero_unload[] = {REG_CLEAR_UNLOAD, 0};
    assert_write_refused(zero_unload, sizeof zero_unload);
    const uint8_t homing2[] = {REG_HOMING, 2};
    assert_write_refused(homing2, sizeof homing2);
    /* VECTORS.md rows, verbatim. */
    const uint8_t id254[] = {0xD5, 0x5D, 0x01, 0x04, 0x03, 0x03, 0xFE, 0x09};
    const uint8_t moving[] = {0xD5, 0x5D, 0x01, 0x04, 0x03, 0x2A, 0x01, 0x33};
    const uint8_t err[] = {0xD5, 0x5D, 0x01, 0x02, 0x20, 0x23};
    assert_answer(xfer(id254, sizeof id254), err, sizeof err);
    assert_answer(xfer(moving, sizeof moving), err, sizeof err);
    assert_int_equal(s.regs.mem[REG_ID], 1);
    assert_int_equal(s.regs.mem[REG_MOVING], 0);
}

static void write_goal_clamped_to_limits(void **state)
{
    (void)state;
    set_reg(REG_CW_LIMIT, 20);
    set_reg(REG_CCW_LIMIT, 300);
    assert_status(write2(1, REG_GOAL_POSITION, 1000), 1, 0x00); /* not an error */
    assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), 300);
    assert_status(write2(1, REG_GOAL_POSITION, 3), 1, 0x00);
    assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), 20);
    assert_status(write2(1, REG_GOAL_POSITION, 150), 1, 0x00);
    assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), 150);
}

static void clear_unload_reads_zero(void **state)
{
    (void)state;
    assert_status(write1(1, REG_CLEAR_UNLOAD, 1), 1, 0x00);
    struct answer a = read_cmd(1, REG_CLEAR_UNLOAD, 1);
    assert_int_equal(a.n, 7);
    assert_int_equal(a.b[5], 0);
}

/* ---- REG WRITE / ACTION (§4.4) -------------------------------------------------------- */

static void reg_write_then_action(void **state)
{
    (void)state;
    const uint8_t rw[] = {0xD5, 0x5D, 0x01, 0x05, 0x04, 0x1E, 0x00, 0x02, 0x2A};
    const uint8_t ok[] = {0xD5, 0x5D, 0x01, 0x02, 0x00, 0x03};
    assert_answer(xfer(rw, sizeof rw), ok, sizeof ok);
    assert_int_equal(s.regs.mem[REG_REGISTERED], 1);
    assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), 0); /* held, not applied */
    struct answer a = read_cmd(1, REG_REGISTERED, 1);
    assert_int_equal(a.b[5], 1);
    const uint8_t action[] = {0xD5, 0x5D, 0xFE, 0x02, 0x05, 0x05};
    assert_silent(xfer(action, sizeof action));
    assert_int_equal(s.regs.mem[REG_REGISTERED], 0);
    assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), 360); /* 0x200 clamped */
    /* Nothing held any more. */
    const uint8_t action1[] = {0xD5, 0x5D, 0x01, 0x02, 0x05, 0x08};
    const uint8_t err[] = {0xD5, 0x5D, 0x01, 0x02, 0x20, 0x23};
    assert_answer(xfer(action1, sizeof action1), err, sizeof err);
}

static void later_reg_write_replaces_held_one(void **state)
{
    (void)state;
    const uint8_t a1[] = {REG_MOVING_SPEED, 100, 0};
    const uint8_t a2[] = {REG_RETURN_DELAY, 7};
    assert_status(cmd(1, INS_REG_WRITE, a1, sizeof a1), 1, 0x00);
    assert_status(cmd(1, INS_REG_WRITE, a2, sizeof a2), 1, 0x00);
    assert_status(cmd(1, INS_ACTION, 0, 0), 1, 0x00);
    assert_int_equal(s.regs.mem[REG_RETURN_DELAY], 7);
    assert_int_equal(regs_get(&s.regs, REG_MOVING_SPEED), 0);
}

static void invalid_reg_write_refused_and_keeps_held(void **state)
{
    (void)state;
    const uint8_t good[] = {REG_MOVING_SPEED, 100, 0};
    const uint8_t bad[] = {REG_MOVING, 1};
    assert_status(cmd(1, INS_REG_WRITE, good, sizeof good), 1, 0x00);
    assert_status(cmd(1, INS_REG_WRITE, bad, sizeof bad), 1, ERR_INSTRUCTION);
    assert_int_equal(s.regs.mem[REG_REGISTERED], 1);
    assert_status(cmd(1, INS_ACTION, 0, 0), 1, 0x00);
    assert_int_equal(regs_get(&s.regs, REG_MOVING_SPEED), 100);
    assert_int_equal(s.regs.mem[REG_MOVING], 0);
    /* With nothing held, a bad REG WRITE leaves register 44 at 0. */
    assert_status(cmd(1, INS_REG_WRITE, bad, sizeof bad), 1, ERR_INSTRUCTION);
    assert_int_equal(s.regs.mem[REG_REGISTERED], 0);
    const uint8_t none[] = {REG_ID};
    assert_status(cmd(1, INS_REG_WRITE, none, 1), 1, ERR_INSTRUCTION);
    assert_status(cmd(1, INS_ACTION, 0, 0), 1, ERR_INSTRUCTION);
}

/* ---- SYNC WRITE ------------------------------------------------------------------ */

static const uint8_t SYNC_SPEED[] = {0xD5, 0x5D, 0xFE, 0x0A, 0x83, 0x20, 0x02, 0x01,
                                     0x64, 0x00, 0x02, 0x64, 0x80, 0xF8};

static void sync_write_takes_own_slice(void **state)
{
    (void)state;
    assert_silent(xfer(SYNC_SPEED, sizeof SYNC_SPEED));
    assert_int_equal(regs_get(&s.regs, REG_MOVING_SPEED), 0x0064);

    power_up(&board_foot);
    set_reg(REG_ID, 2);
    assert_silent(xfer(SYNC_SPEED, sizeof SYNC_SPEED));
    assert_int_equal(regs_get(&s.regs, REG_MOVING_SPEED), 0x8064);

    power_up(&board_foot);
    set_reg(REG_ID, 3);
    assert_silent(xfer(SYNC_SPEED, sizeof SYNC_SPEED));
    assert_int_equal(regs_get(&s.regs, REG_MOVING_SPEED), 0);

    /* Three servos, 2 bytes each (registers 16 and 17): servo 7 takes the last slice. */
    power_up(&board_foot);
    set_reg(REG_ID, 7);
    const uint8_t p[] = {REG_STATUS_RETURN_LEVEL, 2, 5, 1, 1, 6, 2, 0, 7, 1, 0};
    assert_silent(cmd(PROTO_ID_BROADCAST, INS_SYNC_WRITE, p, sizeof p));
    assert_int_equal(s.regs.mem[REG_STATUS_RETURN_LEVEL], 1);
    assert_int_equal(s.regs.mem[REG_HEARTBEAT_ENABLE], 0);
}

static void sync_write_malformed_or_invalid_ignored(void **state)
{
    (void)state;
    uint8_t before[REGS_SIZE];
    memcpy(before, s.regs.mem, REGS_SIZE);
    /* Length does not fit (L+1)*k: one byte short of the second slice. */
    const uint8_t shortp[] = {REG_MOVING_SPEED, 2, 1, 0x64, 0x00, 2, 0x64};
    assert_silent(cmd(PROTO_ID_BROADCAST, INS_SYNC_WRITE, shortp, sizeof shortp));
    /* L = 0. */
    const uint8_t l0[] = {REG_MOVING_SPEED, 0, 1, 2};
    assert_silent(cmd(PROTO_ID_BROADCAST, INS_SYNC_WRITE, l0, sizeof l0));
    /* No slices at all. */
    const uint8_t empty[] = {REG_MOVING_SPEED, 2};
    assert_silent(cmd(PROTO_ID_BROADCAST, INS_SYNC_WRITE, empty, sizeof empty));
    /* Our slice would write half of a 16-bit register. */
    const uint8_t halfp[] = {REG_MOVING_SPEED, 1, 1, 0x64};
    assert_silent(cmd(PROTO_ID_BROADCAST, INS_SYNC_WRITE, halfp, sizeof halfp));
    /* Our slice is out of range. */
    const uint8_t range[] = {REG_STATUS_RETURN_LEVEL, 1, 2, 1, 1, 9};
    assert_silent(cmd(PROTO_ID_BROADCAST, INS_SYNC_WRITE, range, sizeof range));
    assert_memory_equal(s.regs.mem, before, REGS_SIZE);
}

static void sync_write_unicast_refused(void **state)
{
    (void)state;
    uint8_t p[sizeof SYNC_SPEED];
    memcpy(p, SYNC_SPEED, sizeof p);
    p[2] = 0x01;
    p[sizeof p - 1u] = proto_sum(&p[2], (uint16_t)(sizeof p - 3u));
    assert_status(xfer(p, sizeof p), 1, ERR_INSTRUCTION);
    assert_int_equal(regs_get(&s.regs, REG_MOVING_SPEED), 0);
}

/* L = 255: the slice stride L + 1 does not fit a byte. The packet cannot fit (§3.1), so
 * it must be refused - not crash the servo. Kept last: a crash here ends the program. */
static void sync_write_slice_of_255_refused(void **state)
{
    (void)state;
    uint8_t before[REGS_SIZE];
    memcpy(before, s.regs.mem, REGS_SIZE);
    const uint8_t p[] = {REG_MOVING_SPEED, 0xFF, 1, 0x64, 0x00};
    assert_silent(cmd(PROTO_ID_BROADCAST, INS_SYNC_WRITE, p, sizeof p));
    assert_memory_equal(s.regs.mem, before, REGS_SIZE);
    const uint8_t ping[] = {0xD5, 0x5D, 0x01, 0x03, 0x01, 0x00, 0x05};
    assert_answer(cmd(1, INS_PING, 0, 0), ping, sizeof ping); /* still alive */
}

/* ---- RESET (§4.5) --------------------------------------------------------------- */

static void reset_restores_factory_values(void **state)
{
    (void)state;
    set_reg(REG_CCW_LIMIT, 200);
    set_reg(REG_CW_LIMIT, 10);
    set_reg(REG_TEMPERATURE_LIMIT, 70);
    set_reg(REG_HEARTBEAT_ENABLE, 0);
    set_reg(REG_UNLOAD_CONDITIONS, 0x30);
    set_reg(REG_HOMING_ZERO_SIDE, 2);
    set_reg(REG_RETURN_DELAY, 2);
    set_reg(REG_MOVING_SPEED, 55);
    set_reg(REG_ACCELERATION, 3);
    set_reg(REG_SLEEP, 1);
    const uint8_t held[] = {REG_BRAKE, 1};
    assert_status(cmd(1, INS_REG_WRITE, held, sizeof held), 1, 0x00);
    const uint8_t traj[] = {1, 50, 0, 10};
    assert_status(cmd(1, INS_TRAJ_WRITE, traj, sizeof traj), 1, 0x00);
    assert_int_equal(s.traj.count, 1);
    set_reg(REG_ID, 5);

    /* The answer comes from the old ID. */
    assert_status(cmd(5, INS_RESET, 0, 0), 5, 0x00);
    struct regs factory;
    regs_init(&factory, &board_foot);
    regs_set(&factory, REG_GOAL_POSITION, regs_present_position(&s.regs));
    assert_memory_equal(s.regs.mem, factory.mem, REGS_SIZE);
    assert_int_equal(s.regs.mem[REG_ID], 1);
    assert_int_equal(s.link.id, 1);
    assert_int_equal(s.link.delay, 16);
    assert_int_equal(s.traj.count, 0);
    assert_int_equal(fake.reset_calls, 1);
    /* Nothing held any more; the old ID is gone, ID 1 answers. */
    assert_silent(cmd(5, INS_PING, 0, 0));
    assert_status(cmd(1, INS_ACTION, 0, 0), 1, ERR_INSTRUCTION);
    assert_int_equal(s.regs.mem[REG_BRAKE], 0);
}

static void reset_answered_at_old_baud(void **state)
{
    (void)state;
    set_reg(REG_BAUD_RATE, 3);
    assert_int_equal(s.link.baud, 38400);
    struct answer a = cmd(1, INS_RESET, 0, 0);
    assert_status(a, 1, 0x00);
    assert_int_equal(a.baud, 38400);
    assert_int_equal(s.link.baud, 9600);
    assert_int_equal(hal.baud, 9600);
    assert_int_equal(s.regs.mem[REG_BAUD_RATE], 0);
}

static void reset_with_parameters_refused(void **state)
{
    (void)state;
    set_reg(REG_RETURN_DELAY, 3);
    const uint8_t p[] = {0};
    assert_status(cmd(1, INS_RESET, p, 1), 1, ERR_INSTRUCTION);
    assert_int_equal(s.regs.mem[REG_RETURN_DELAY], 3);
}

/* ---- who answers (§3.2) ---------------------------------------------------------- */

static void broadcast_is_executed_in_silence(void **state)
{
    (void)state;
    const uint8_t bc = PROTO_ID_BROADCAST;
    assert_silent(write1(bc, REG_RETURN_DELAY, 4));
    assert_int_equal(s.regs.mem[REG_RETURN_DELAY], 4);
    assert_silent(read_cmd(bc, REG_ID, 1));
    assert_silent(read_cmd(bc, REG_ID, 0));                 /* an error: silent too */
    assert_silent(write1(bc, REG_MOVING, 1));
    assert_silent(cmd(bc, 0x09, 0, 0));                 /* undefined */
    const uint8_t rw[] = {REG_MOVING_SPEED, 9, 0};
    assert_silent(cmd(bc, INS_REG_WRITE, rw, sizeof rw));
    assert_int_equal(s.regs.mem[REG_REGISTERED], 1);
    assert_silent(cmd(bc, INS_ACTION, 0, 0));
    assert_int_equal(regs_get(&s.regs, REG_MOVING_SPEED), 9);
    const uint8_t traj[] = {1, 50, 0, 10};
    assert_silent(cmd(bc, INS_TRAJ_WRITE, traj, sizeof traj));
    assert_int_equal(s.traj.count, 1);
    const uint8_t ping_p[] = {1};
    assert_silent(cmd(bc, INS_PING, ping_p, 1));        /* a bad PING */
    /* The source's example: broadcast WRITE ID := 1. */
    const uint8_t src[] = {0xD5, 0x5D, 0xFE, 0x04, 0x03, 0x03, 0x01, 0x09};
    set_reg(REG_ID, 4);
    assert_silent(xfer(src, sizeof src));
    assert_int_equal(s.regs.mem[REG_ID], 1);
    assert_int_equal(s.link.id, 1);
    assert_silent(cmd(bc, INS_RESET, 0, 0));
    assert_int_equal(s.regs.mem[REG_RETURN_DELAY], 16);
}

static void other_ids_ignored(void **state)
{
    (void)state;
    assert_silent(write1(2, REG_RETURN_DELAY, 4));
    assert_silent(cmd(0, INS_PING, 0, 0));
    assert_silent(cmd(0xFD, INS_RESET, 0, 0));
    assert_int_equal(s.regs.mem[REG_RETURN_DELAY], 16);
}

static void status_level_1_answers_read_and_ping_only(void **state)
{
    (void)state;
    set_reg(REG_STATUS_RETURN_LEVEL, 1);
    assert_silent(write1(1, REG_RETURN_DELAY, 4));
    assert_int_equal(s.regs.mem[REG_RETURN_DELAY], 4);  /* executed */
    assert_silent(write1(1, REG_MOVING, 1));             /* an error: silent too */
    assert_silent(cmd(1, INS_ACTION, 0, 0));
    struct answer a = read_cmd(1, REG_RETURN_DELAY, 1);
    const uint8_t want[] = {0xD5, 0x5D, 0x01, 0x03, 0x00, 0x04, 0x08};
    assert_answer(a, want, sizeof want);
    assert_status(read_cmd(1, REG_ID, 0), 1, ERR_INSTRUCTION); /* a READ error is a READ */
    assert_int_equal(cmd(1, INS_PING, 0, 0).n, 7);
    /* A bad checksum is answered only at level 2. */
    const uint8_t bad[] = {0xD5, 0x5D, 0x01, 0x04, 0x02, 0x03, 0x01, 0x0C};
    assert_silent(xfer(bad, sizeof bad));
}

static void status_level_0_answers_ping_only(void **state)
{
    (void)state;
    set_reg(REG_STATUS_RETURN_LEVEL, 0);
    assert_silent(read_cmd(1, REG_ID, 1));
    assert_silent(write1(1, REG_RETURN_DELAY, 4));
    assert_int_equal(s.regs.mem[REG_RETURN_DELAY], 4);
    assert_silent(read_cmd(1, REG_ID, 0));
    const uint8_t bad[] = {0xD5, 0x5D, 0x01, 0x04, 0x02, 0x03, 0x01, 0x0C};
    assert_silent(xfer(bad, sizeof bad));
    assert_int_equal(cmd(1, INS_PING, 0, 0).n, 7);
}

/* ---- ERR bits 4 and 5 and register 18 (§3.1, §3.2, §7.2) ------------------------------ */

static void bad_checksum_answered_and_not_executed(void **state)
{
    (void)state;
    const uint8_t bad[] = {0xD5, 0x5D, 0x01, 0x04, 0x03, 0x05, 0x00, 0x0E};
    const uint8_t want[] = {0xD5, 0x5D, 0x01, 0x02, 0x10, 0x13};
    assert_answer(xfer(bad, sizeof bad), want, sizeof want);
    assert_int_equal(s.regs.mem[REG_RETURN_DELAY], 16);
    /* The bit describes that packet only: the next good one is answered clean. */
    assert_status(write1(1, REG_RETURN_DELAY, 0), 1, 0x00);
    /* Bad checksums on a broadcast or to another ID: silence. */
    const uint8_t bc[] = {0xD5, 0x5D, 0xFE, 0x04, 0x03, 0x05, 0x07, 0x00};
    assert_silent(xfer(bc, sizeof bc));
    const uint8_t other[] = {0xD5, 0x5D, 0x02, 0x04, 0x03, 0x05, 0x07, 0x00};
    assert_silent(xfer(other, sizeof other));
    assert_int_equal(s.regs.mem[REG_RETURN_DELAY], 0);
}

static void checksum_report_bit_off_means_no_bit_4(void **state)
{
    (void)state;
    set_reg(REG_UNLOAD_CONDITIONS, 0x7F & ~UNLOAD_REPORT_CHECKSUM);
    const uint8_t bad[] = {0xD5, 0x5D, 0x01, 0x04, 0x03, 0x05, 0x00, 0x0E};
    assert_silent(xfer(bad, sizeof bad));
    assert_int_equal(s.regs.mem[REG_RETURN_DELAY], 16);
}

static void instruction_report_bit_off_means_no_bit_5(void **state)
{
    (void)state;
    set_reg(REG_UNLOAD_CONDITIONS, 0x7F & ~UNLOAD_REPORT_INSTRUCTION);
    struct answer a = write1(1, REG_MOVING, 1);
    /* Whether the servo stays silent or answers without the bit, bit 5 is not shown. */
    if (a.n)
        assert_int_equal(a.b[4] & ERR_INSTRUCTION, 0);
    assert_int_equal(s.regs.mem[REG_MOVING], 0);
    a = read_cmd(1, 48, 5);
    if (a.n)
        assert_int_equal(a.b[4] & ERR_INSTRUCTION, 0);
    /* Good instructions are still answered normally. */
    assert_status(write1(1, REG_RETURN_DELAY, 1), 1, 0x00);
}

static void live_error_bits_in_answers(void **state)
{
    (void)state;
    fake.live_err = ERR_OVER_VOLTAGE | ERR_STALL;
    assert_status(write1(1, REG_RETURN_DELAY, 1), 1, ERR_OVER_VOLTAGE | ERR_STALL);
    assert_status(write1(1, REG_MOVING, 1), 1, ERR_OVER_VOLTAGE | ERR_STALL | ERR_INSTRUCTION);
    struct answer a = read_cmd(1, REG_ID, 1);
    assert_int_equal(a.b[4], ERR_OVER_VOLTAGE | ERR_STALL);
}

static void undefined_instruction_refused(void **state)
{
    (void)state;
    const uint8_t p[] = {0xD5, 0x5D, 0x01, 0x02, 0x09, 0x0C};
    const uint8_t want[] = {0xD5, 0x5D, 0x01, 0x02, 0x20, 0x23};
    assert_answer(xfer(p, sizeof p), want, sizeof want);
    const uint8_t ins[] = {0x00, 0x08, 0x0C, 0x80, 0x82, 0x84, 0xFE};
    for (size_t i = 0; i < sizeof ins; i++)
        assert_status(cmd(1, ins[i], 0, 0), 1, ERR_INSTRUCTION);
    /* The codes that read as an ERR byte reporting an error (0x10-0x3F, 0x50-0x7F) are
     * refused as §3.1 says whenever the frame has parameters; only the exact shape of an
     * error answer (no parameters) goes unanswered: it is another servo's error answer
     * at this ID (docs/decisions.md, duplicate IDs). */
    const uint8_t errlike[] = {0x10, 0x20, 0x21, 0x3F, 0x50, 0x60, 0x7E};
    const uint8_t one = 0x00;
    for (size_t i = 0; i < sizeof errlike; i++) {
        assert_status(cmd(1, errlike[i], &one, 1), 1, ERR_INSTRUCTION);
        assert_silent(cmd(1, errlike[i], 0, 0));
    }
}

/* dispatch_frame() on a hand-built frame: what the main loop hands over. */
static void dispatch_frame_schedules_answer(void **state)
{
    (void)state;
    struct frame f;
    uint8_t buf[FRAME_BYTES];
    memset(&f, 0, sizeof f);
    f.buf = buf;
    const uint8_t body[] = {0x01, 0x04, 0x02, 0x03, 0x01, 0x0B}; /* READ ID */
    memcpy(f.buf, body, sizeof body);
    f.len = sizeof body;
    f.status = FRAME_OK;
    f.end_us = 123456u;
    dispatch_frame(&s, &f);
    assert_int_equal(s.link.state, LINK_WAITING);
    assert_int_equal(s.link.due_us, 123456u + 16u * 500u);
    const uint8_t want[] = {0xD5, 0x5D, 0x01, 0x03, 0x00, 0x01, 0x05};
    assert_int_equal(s.link.tx_len, sizeof want);
    assert_memory_equal(s.link.tx, want, sizeof want);

    /* The same frame with a bad checksum: ERR bit 4, no parameters. */
    power_up(&board_foot);
    f.status = FRAME_BAD_CHECKSUM;
    dispatch_frame(&s, &f);
    assert_int_equal(s.link.state, LINK_WAITING);
    const uint8_t bad[] = {0xD5, 0x5D, 0x01, 0x02, 0x10, 0x13};
    assert_int_equal(s.link.tx_len, sizeof bad);
    assert_memory_equal(s.link.tx, bad, sizeof bad);
}

/* ---- START/END (§4.6) -------------------------------------------------------------- */

static void start_end_validation(void **state)
{
    (void)state;
    const uint8_t what[] = {0, 3, 0x80, 0xFF};
    for (size_t i = 0; i < sizeof what; i++)
        assert_status(cmd(1, INS_START_END, &what[i], 1), 1, ERR_INSTRUCTION);
    assert_status(cmd(1, INS_START_END, 0, 0), 1, ERR_INSTRUCTION);
    const uint8_t two[] = {1, 1};
    assert_status(cmd(1, INS_START_END, two, 2), 1, ERR_INSTRUCTION);
    assert_int_equal(fake.start_end_calls, 0);
    /* Speed mode (both limits 0): refused whatever the value. */
    const uint8_t zero[] = {REG_CW_LIMIT, 0, 0, 0, 0};
    assert_status(cmd(1, INS_WRITE, zero, sizeof zero), 1, 0x00);
    const uint8_t one = 1, two1 = 2;
    assert_status(cmd(1, INS_START_END, &one, 1), 1, ERR_INSTRUCTION);
    assert_status(cmd(1, INS_START_END, &two1, 1), 1, ERR_INSTRUCTION);
    /* The base is always in speed mode. */
    power_up(&board_base);
    assert_status(cmd(1, INS_START_END, &one, 1), 1, ERR_INSTRUCTION);
    set_reg(REG_CCW_LIMIT, 100);
    assert_status(cmd(1, INS_START_END, &two1, 1), 1, ERR_INSTRUCTION);
    assert_int_equal(fake.start_end_calls, 0);
}

static void start_end_valid_reaches_motion(void **state)
{
    (void)state;
    for (uint8_t w = 1; w <= 2; w++) {
        fake.start_end_calls = 0;
        assert_status(cmd(1, INS_START_END, &w, 1), 1, 0x00);
        assert_int_equal(fake.start_end_calls, 1);
        assert_int_equal(fake.start_end_what, w);
    }
    fake.result = ERR_INSTRUCTION; /* the motion layer's refusal is passed on */
    const uint8_t one = 1;
    assert_status(cmd(1, INS_START_END, &one, 1), 1, ERR_INSTRUCTION);
}

/* ---- TRAJECTORY (§4.7) --------------------------------------------------------------- */

static void trajectory_write_and_action(void **state)
{
    (void)state;
    const uint8_t act[] = {0xD5, 0x5D, 0x01, 0x02, 0x0B, 0x0E};
    assert_status(xfer(act, sizeof act), 1, ERR_INSTRUCTION); /* nothing stored */
    const uint8_t w4[] = {0xD5, 0x5D, 0x01, 0x0B, 0x0A, 0x02, 0x0A, 0x00,
                          0x32, 0x00, 0x14, 0x00, 0x32, 0x00, 0x9A};
    const uint8_t ok[] = {0xD5, 0x5D, 0x01, 0x02, 0x00, 0x03};
    assert_answer(xfer(w4, sizeof w4), ok, sizeof ok);
    assert_int_equal(s.traj.count, 2);
    const uint8_t w3[] = {0xD5, 0x5D, 0x01, 0x09, 0x0A, 0x02, 0x0A, 0x00,
                          0x32, 0x14, 0x00, 0x32, 0x98};
    assert_answer(xfer(w3, sizeof w3), ok, sizeof ok);
    assert_int_equal(s.traj.count, 2);
    assert_int_equal(s.traj.pt[1].angle, 20);
    const uint8_t bad[] = {2, 10, 0, 5, 0, 20, 0, 0, 0}; /* speed 0 */
    assert_status(cmd(1, INS_TRAJ_WRITE, bad, sizeof bad), 1, ERR_INSTRUCTION);
    assert_int_equal(s.traj.count, 2);
    assert_int_equal(s.traj.pt[1].speed, 50);
    const uint8_t extra = 0;
    assert_status(cmd(1, INS_TRAJ_ACTION, &extra, 1), 1, ERR_INSTRUCTION);
    assert_int_equal(fake.traj_action_calls, 0);
    assert_answer(xfer(act, sizeof act), ok, sizeof ok);
    assert_int_equal(fake.traj_action_calls, 1);
    assert_int_equal(s.traj.count, 2); /* the points remain */
    /* The most one packet carries: 84 points of 3 bytes, LEN 255. */
    uint8_t p[253];
    p[0] = 84;
    for (uint8_t i = 0; i < 84; i++) {
        p[1 + 3 * i] = i;
        p[2 + 3 * i] = 0;
        p[3 + 3 * i] = 9;
    }
    assert_status(cmd(1, INS_TRAJ_WRITE, p, sizeof p), 1, 0x00);
    assert_int_equal(s.traj.count, 84);
    assert_int_equal(s.traj.pt[83].angle, 83);
}

/* ---- CUSTOM MOVE (§4.8) ------------------------------------------------------------- */

static void custom_bad_subs_and_lengths_refused(void **state)
{
    (void)state;
    const uint8_t p[] = {0x01, 0x2D, 0x00, 0x14, 0x80, 0x24, 0x24, 0x00};
    const uint8_t q[] = {0x02, 0x5A, 0x00, 0x1E, 0x00, 0x24, 0x24, 0x00};
    assert_status(cmd(1, INS_CUSTOM, p, 0), 1, ERR_INSTRUCTION); /* no sub */
    assert_status(cmd(1, INS_CUSTOM, p, 1), 1, ERR_INSTRUCTION);
    assert_status(cmd(1, INS_CUSTOM, p, 3), 1, ERR_INSTRUCTION);
    assert_status(cmd(1, INS_CUSTOM, p, 4), 1, ERR_INSTRUCTION); /* 3 params */
    assert_status(cmd(1, INS_CUSTOM, p, 6), 1, ERR_INSTRUCTION); /* 5 params */
    assert_status(cmd(1, INS_CUSTOM, p, 8), 1, ERR_INSTRUCTION); /* 7 params */
    assert_status(cmd(1, INS_CUSTOM, q, 5), 1, ERR_INSTRUCTION); /* sub 2, 4 params */
    assert_status(cmd(1, INS_CUSTOM, q, 6), 1, ERR_INSTRUCTION);
    assert_status(cmd(1, INS_CUSTOM, q, 8), 1, ERR_INSTRUCTION);
    const uint8_t subs[] = {0x00, 0x03, 0x10, 0x80, 0xFF};
    for (size_t i = 0; i < sizeof subs; i++) {
        uint8_t r[7] = {subs[i], 0x5A, 0x00, 0x1E, 0x00, 0x24, 0x24};
        assert_status(cmd(1, INS_CUSTOM, r, 5), 1, ERR_INSTRUCTION);
        assert_status(cmd(1, INS_CUSTOM, r, 7), 1, ERR_INSTRUCTION);
    }
    assert_int_equal(fake.custom_calls, 0);
}

static void custom_decoding(void **state)
{
    (void)state;
    /* VECTORS.md: relative 45 in the negative direction at 20/s. */
    const uint8_t rel[] = {0xD5, 0x5D, 0x01, 0x07, 0xFF, 0x01, 0x2D, 0x00, 0x14, 0x80, 0xC9};
    const uint8_t ok[] = {0xD5, 0x5D, 0x01, 0x02, 0x00, 0x03};
    assert_answer(xfer(rel, sizeof rel), ok, sizeof ok);
    assert_int_equal(fake.custom_calls, 1);
    assert_int_equal(fake.custom.absolute, 0);
    assert_int_equal(fake.custom.has_ramps, 0);
    assert_int_equal(fake.custom.target, 45);
    assert_int_equal(fake.custom.speed, 0x8014);
    /* Relative with acceleration and deceleration. */
    const uint8_t rel6[] = {0x01, 0x34, 0x12, 0x0A, 0x00, 0x05, 0x07};
    assert_status(cmd(1, INS_CUSTOM, rel6, sizeof rel6), 1, 0x00);
    assert_int_equal(fake.custom_calls, 2);
    assert_int_equal(fake.custom.absolute, 0);
    assert_int_equal(fake.custom.has_ramps, 1);
    assert_int_equal(fake.custom.target, 0x1234);
    assert_int_equal(fake.custom.speed, 10);
    assert_int_equal(fake.custom.acc, 5);
    assert_int_equal(fake.custom.dec, 7);
    /* VECTORS.md: absolute to 90 at 30/s, acc 36, dec 36. */
    const uint8_t abs6[] = {0xD5, 0x5D, 0x01, 0x09, 0xFF, 0x02, 0x5A, 0x00,
                            0x1E, 0x00, 0x24, 0x24, 0xCB};
    assert_answer(xfer(abs6, sizeof abs6), ok, sizeof ok);
    assert_int_equal(fake.custom_calls, 3);
    assert_int_equal(fake.custom.absolute, 1);
    assert_int_equal(fake.custom.has_ramps, 1);
    assert_int_equal(fake.custom.target, 90);
    assert_int_equal(fake.custom.speed, 30);
    assert_int_equal(fake.custom.acc, 36);
    assert_int_equal(fake.custom.dec, 36);
}

/* ---- resolution (§5) ------------------------------------------------------------- */

static void refused_resolution_changes_nothing(void **state)
{
    (void)state;
    const uint8_t traj[] = {1, 100, 0, 10};
    assert_status(cmd(1, INS_TRAJ_WRITE, traj, sizeof traj), 1, 0x00);
    const uint8_t p[] = {REG_RESOLUTION, 0};
    assert_status(cmd(1, INS_WRITE, p, sizeof p), 1, ERR_INSTRUCTION);
    assert_int_equal(s.regs.mem[REG_RESOLUTION], 10);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 360);
    assert_int_equal(s.traj.count, 1);
}

int main(void)
{
#define T(f) cmocka_unit_test_setup(f, setup_foot)
    const struct CMUnitTest tests[] = {
        T(ping_answer_format),
        T(ping_answered_at_every_level),
        T(broadcast_ping_answered_with_own_id),
        T(ping_with_parameters_refused),
        T(read_answers),
        T(read_hidden_addresses_as_zero),
        T(read_errors),
        T(write_applies_and_answers),
        T(write_all_or_nothing),
        T(write_goal_clamped_to_limits),
        T(clear_unload_reads_zero),
        T(reg_write_then_action),
        T(later_reg_write_replaces_held_one),
        T(invalid_reg_write_refused_and_keeps_held),
        T(sync_write_takes_own_slice),
        T(sync_write_malformed_or_invalid_ignored),
        T(sync_write_unicast_refused),
        T(reset_restores_factory_values),
        T(reset_answered_at_old_baud),
        T(reset_with_parameters_refused),
        T(broadcast_is_executed_in_silence),
        T(other_ids_ignored),
        T(status_level_1_answers_read_and_ping_only),
        T(status_level_0_answers_ping_only),
        T(bad_checksum_answered_and_not_executed),
        T(checksum_report_bit_off_means_no_bit_4),
        T(instruction_report_bit_off_means_no_bit_5),
        T(live_error_bits_in_answers),
        T(undefined_instruction_refused),
        T(dispatch_frame_schedules_answer),
        T(start_end_validation),
        T(start_end_valid_reaches_motion),
        T(trajectory_write_and_action),
        T(custom_bad_subs_and_lengths_refused),
        T(custom_decoding),
        T(refused_resolution_changes_nothing),
        T(sync_write_slice_of_255_refused), /* last: may take the program down */
    };
#undef T
    return cmocka_run_group_tests(tests, 0, 0);
}
