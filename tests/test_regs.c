/* test_regs.c - the control table (PROTOCOL.md §5.1, §8): descriptors, factory defaults
 * per variant, applicability, write validation, READ visibility and goal clamping. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "board.h"
#include "link.h"
#include "proto.h"
#include "regs.h"


/* Addresses that §5.1 marks reserved. */
static const uint8_t reserved[] = {10, 14, 15, 23, 26, 27, 28, 29, 45};

/* Addresses where a 16-bit register starts (§5.1). */
static const uint8_t wide[] = {0, 6, 8, 30, 32, 36, 38, 40};

static bool is_reserved(uint8_t a)
{
    for (size_t i = 0; i < sizeof reserved; i++)
        if (reserved[i] == a)
            return true;
    return false;
}

static bool valid(const struct regs *r, uint8_t addr, const uint8_t *d, uint8_t n)
{
    return regs_write_valid(r, addr, d, n);
}

static bool valid1(const struct regs *r, uint8_t addr, uint8_t v)
{
    return regs_write_valid(r, addr, &v, 1);
}

static bool valid2(const struct regs *r, uint8_t addr, uint16_t v)
{
    const uint8_t d[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    return regs_write_valid(r, addr, d, 2);
}

/* ---- descriptors ---------------------------------------------------------------- */

static void descriptors_are_sane(void **state)
{
    (void)state;
    for (uint8_t a = 0; a < REGS_SIZE; a++) {
        const struct reg_desc *d = &regs_table[a];
        assert_true(d->size <= 2);
        if (d->size == 0)
            continue;
        assert_true(d->min <= regs_max(d));
        assert_true(d->access == REG_ACCESS_R || d->access == REG_ACCESS_W ||
                    d->access == REG_ACCESS_RW);
        assert_true(d->area == REG_AREA_EE || d->area == REG_AREA_RAM);
        assert_int_not_equal(d->variants & REG_V_ALL, 0);
        assert_true(a + d->size <= REGS_SIZE);
        if (d->size == 2) {
            assert_int_equal(a % 2, 0); /* one aligned halfword store on the MCU */
            assert_int_equal(regs_table[a + 1].size, 0); /* high byte: no register */
        } else {
            assert_true(regs_max(d) <= 0xFF);
        }
    }
}

static void sixteen_bit_registers_are_the_specs(void **state)
{
    (void)state;
    for (uint8_t a = 0; a < REGS_SIZE; a++) {
        bool w = false;
        for (size_t i = 0; i < sizeof wide; i++)
            w = w || wide[i] == a;
        if (w)
            assert_int_equal(regs_table[a].size, 2);
        else if (a && regs_table[a - 1].size == 2)
            assert_int_equal(regs_table[a].size, 0);
        else if (is_reserved(a))
            assert_int_equal(regs_table[a].size, 0);
        else
            assert_int_equal(regs_table[a].size, 1);
    }
}

static void no_overlapping_registers(void **state)
{
    (void)state;
    uint8_t owner[REGS_SIZE];
    memset(owner, 0xFF, sizeof owner);
    for (uint8_t a = 0; a < REGS_SIZE; a++)
        for (uint8_t k = 0; k < regs_table[a].size; k++) {
            assert_true(a + k < REGS_SIZE);
            assert_int_equal(owner[a + k], 0xFF);
            owner[a + k] = a;
        }
}

static void defaults_within_range_on_every_board(void **state)
{
    (void)state;
    for (size_t b = 0; b < BOARD_COUNT; b++)
        for (uint8_t a = 0; a < REGS_SIZE; a++) {
            /* A write-only command (25, "clear unload") has no value to default: §5.1
             * gives "-" and it reads 0, so only readable registers are checked. */
            if (!regs_applicable(board_all[b], a) || !(regs_table[a].access & REG_ACCESS_R))
                continue;
            uint16_t v = regs_default(board_all[b], a);
            assert_true(v >= regs_table[a].min);
            assert_true(v <= regs_max(&regs_table[a]));
            if (regs_table[a].size == 1)
                assert_true(v <= 0xFF);
        }
}

static void reserved_addresses_exist_nowhere(void **state)
{
    (void)state;
    for (size_t b = 0; b < BOARD_COUNT; b++) {
        for (size_t i = 0; i < sizeof reserved; i++) {
            assert_false(regs_applicable(board_all[b], reserved[i]));
            assert_int_equal(regs_default(board_all[b], reserved[i]), 0);
        }
        assert_false(regs_applicable(board_all[b], REGS_SIZE));
        assert_false(regs_applicable(board_all[b], 0xFF));
    }
}

/* ---- factory defaults per variant (§5.1, §8) --------------------------------------- */

static void factory_defaults_per_variant(void **state)
{
    (void)state;
    for (size_t b = 0; b < BOARD_COUNT; b++) {
        const struct board *bd = board_all[b];
        struct regs r;
        memset(&r, 0x5A, sizeof r);
        regs_init(&r, bd);
        bool base = bd->variant == VARIANT_BASE;
        assert_ptr_equal(r.board, bd);
        assert_int_equal(regs_get(&r, REG_MODEL_NUMBER), bd->model_number);
        assert_int_equal(r.mem[REG_ID], 1);
        assert_int_equal(r.mem[REG_BAUD_RATE], 0);
        assert_int_equal(r.mem[REG_RETURN_DELAY], base ? 8 : 16);
        assert_int_equal(regs_get(&r, REG_CW_LIMIT), 0);
        assert_int_equal(r.mem[REG_TEMPERATURE_LIMIT], 80);
        assert_int_equal(r.mem[REG_CURRENT_LIMIT], bd->current_limit);
        assert_int_equal(r.mem[REG_RESOLUTION], 10);
        /* CCW = the board's range in position units at resolution 10 (0.1 deg x 10). */
        assert_int_equal(regs_get(&r, REG_CCW_LIMIT), bd->max_angle_ddeg / 10u);
        assert_int_equal(r.mem[REG_STATUS_RETURN_LEVEL], 2);
        assert_int_equal(r.mem[REG_HEARTBEAT_ENABLE], 1);
        assert_int_equal(r.mem[REG_UNLOAD_CONDITIONS], 0x7F);
        assert_int_equal(r.mem[REG_HOMING_ZERO_SIDE], 1);
        assert_int_equal(r.mem[REG_RS485_TERMINATION], 0);
        assert_int_equal(r.mem[REG_BASE_ACCELERATION], base ? 36 : 0);
        assert_int_equal(r.mem[REG_BASE_DECELERATION], base ? 36 : 0);
        assert_int_equal(r.mem[REG_ACCELERATION], base ? 0 : 36);
        assert_int_equal(r.mem[REG_DECELERATION], base ? 0 : 36);
        assert_int_equal(r.mem[REG_HOMING], 0);
        assert_int_equal(regs_get(&r, REG_MOVING_SPEED), 0);
        assert_int_equal(r.mem[REG_MOVING], 0);
        assert_int_equal(r.mem[REG_BRAKE], 0);
        assert_int_equal(r.mem[REG_REGISTERED], 0);
        assert_int_equal(r.mem[REG_SLEEP], 0);
        assert_int_equal(r.mem[REG_MOVE_WITHOUT_REFERENCE], 0);
        for (size_t i = 0; i < sizeof reserved; i++)
            assert_int_equal(r.mem[reserved[i]], 0);
        /* Base: CCW 0 (continuous), so speed mode; every other variant position mode. */
        assert_int_equal(regs_speed_mode(&r), base);
    }
    assert_int_equal(regs_default(&board_base, REG_CCW_LIMIT), 0);
    assert_int_equal(regs_default(&board_foot, REG_CCW_LIMIT), 360);
    assert_int_equal(regs_default(&board_wrist, REG_CCW_LIMIT), 270);
    assert_int_equal(regs_default(&board_finger, REG_CCW_LIMIT), 180);
}

/* §8: the base's and the others' default baud and delay. */
static void board_defaults_match_section_8(void **state)
{
    (void)state;
    assert_int_equal(board_base.default_baud, 115200);
    assert_int_equal(board_base.return_delay, 8);
    for (size_t b = 1; b < BOARD_COUNT; b++) {
        assert_int_equal(board_all[b]->default_baud, 9600);
        assert_int_equal(board_all[b]->return_delay, 16);
    }
    assert_int_equal(board_base.photo_switches, 0);
    assert_int_equal(board_foot.photo_switches, 0);
    assert_int_equal(board_arm.photo_switches, 1);
    assert_int_equal(board_wrist.photo_switches, 1);
    assert_int_equal(board_finger.photo_switches, 1);
}

/* ---- applicability (§5.1) -------------------------------------------------------- */

static void variant_applicability(void **state)
{
    (void)state;
    for (size_t b = 0; b < BOARD_COUNT; b++) {
        const struct board *bd = board_all[b];
        bool base = bd->variant == VARIANT_BASE;
        bool wh = bd->variant == VARIANT_WRIST || bd->variant == VARIANT_FINGER;
        assert_int_equal(regs_applicable(bd, REG_BASE_ACCELERATION), base);
        assert_int_equal(regs_applicable(bd, REG_BASE_DECELERATION), base);
        assert_int_equal(regs_applicable(bd, REG_ACCELERATION), !base);
        assert_int_equal(regs_applicable(bd, REG_DECELERATION), !base);
        assert_int_equal(regs_applicable(bd, REG_PRESENT_POSITION), wh);
        assert_int_equal(regs_applicable(bd, REG_TURNED_ANGLE), !wh);
        /* The high byte of a register is never the start of one. */
        for (size_t i = 0; i < sizeof wide; i++)
            assert_false(regs_applicable(bd, (uint8_t)(wide[i] + 1u)));
        /* Everything else that §5.1 lists exists on every variant. */
        const uint8_t common[] = {0, 2, 3, 4, 5, 6, 8, 11, 12, 13, 16, 17, 18, 19, 20,
                                  24, 25, 30, 32, 38, 42, 43, 44, 46, 47, 48, 49};
        for (size_t i = 0; i < sizeof common; i++)
            assert_true(regs_applicable(bd, common[i]));
    }
}

/* ---- regs_write_valid (§4.3) ----------------------------------------------------- */

static void write_ranges(void **state)
{
    (void)state;
    struct regs r;
    regs_init(&r, &board_foot);
    assert_true(valid1(&r, REG_ID, 0));
    assert_true(valid1(&r, REG_ID, 253));
    assert_false(valid1(&r, REG_ID, 254));
    assert_false(valid1(&r, REG_ID, 255));
    assert_true(valid1(&r, REG_BAUD_RATE, 10));
    assert_false(valid1(&r, REG_BAUD_RATE, 11));
    assert_true(valid1(&r, REG_RETURN_DELAY, 255));
    assert_false(valid1(&r, REG_RESOLUTION, 0));
    assert_true(valid1(&r, REG_RESOLUTION, 1));
    assert_true(valid1(&r, REG_RESOLUTION, 255));
    assert_true(valid1(&r, REG_STATUS_RETURN_LEVEL, 2));
    assert_false(valid1(&r, REG_STATUS_RETURN_LEVEL, 3));
    assert_true(valid1(&r, REG_HEARTBEAT_ENABLE, 1));
    assert_false(valid1(&r, REG_HEARTBEAT_ENABLE, 2));
    assert_true(valid1(&r, REG_UNLOAD_CONDITIONS, 0x7F));
    assert_false(valid1(&r, REG_UNLOAD_CONDITIONS, 0x80)); /* bit 7 must be 0 */
    assert_false(valid1(&r, REG_HOMING_ZERO_SIDE, 0));
    assert_true(valid1(&r, REG_HOMING_ZERO_SIDE, 1));
    assert_true(valid1(&r, REG_HOMING_ZERO_SIDE, 2));
    assert_false(valid1(&r, REG_HOMING_ZERO_SIDE, 3));
    assert_true(valid1(&r, REG_RS485_TERMINATION, 1));
    assert_false(valid1(&r, REG_RS485_TERMINATION, 2));
    assert_true(valid1(&r, REG_HOMING, 0));
    assert_true(valid1(&r, REG_HOMING, 1));
    assert_false(valid1(&r, REG_HOMING, 2));
    assert_false(valid1(&r, REG_CLEAR_UNLOAD, 0));
    assert_true(valid1(&r, REG_CLEAR_UNLOAD, 1));
    assert_false(valid1(&r, REG_CLEAR_UNLOAD, 2));
    assert_false(valid1(&r, REG_BRAKE, 2));
    assert_false(valid1(&r, REG_SLEEP, 2));
    assert_false(valid1(&r, REG_MOVE_WITHOUT_REFERENCE, 2));
    assert_true(valid1(&r, REG_TEMPERATURE_LIMIT, 0xFF)); /* bit 7 is the sign */
    assert_true(valid2(&r, REG_GOAL_POSITION, 0xFFFF));  /* out of limits: clamped */
    assert_true(valid2(&r, REG_MOVING_SPEED, 0x8064));   /* bit 15 = direction */
}

static void write_read_only_refused(void **state)
{
    (void)state;
    for (size_t b = 0; b < BOARD_COUNT; b++) {
        struct regs r;
        regs_init(&r, board_all[b]);
        assert_false(valid2(&r, REG_MODEL_NUMBER, regs_get(&r, REG_MODEL_NUMBER)));
        assert_false(valid1(&r, REG_FIRMWARE_VERSION, r.mem[REG_FIRMWARE_VERSION]));
        assert_false(valid2(&r, REG_PRESENT_POSITION, 0));
        assert_false(valid2(&r, REG_PRESENT_SPEED, 0));
        assert_false(valid2(&r, REG_TURNED_ANGLE, 0));
        assert_false(valid1(&r, REG_MOVING, 0));
        assert_false(valid1(&r, REG_REGISTERED, 0));
        assert_false(valid1(&r, REG_PRESENT_TEMPERATURE, 0));
        assert_false(valid1(&r, REG_PHOTO_SWITCHES, 0));
    }
}

static void write_reserved_and_not_applicable_refused(void **state)
{
    (void)state;
    struct regs r;
    regs_init(&r, &board_foot);
    for (size_t i = 0; i < sizeof reserved; i++)
        assert_false(valid1(&r, reserved[i], 0));
    /* A write spanning a reserved byte is refused as a whole. */
    const uint8_t span[] = {80, 0, 40}; /* 11 temperature, 12 current... from 10 */
    assert_false(valid(&r, 10, span, 3));
    const uint8_t span2[] = {10, 0, 0, 2}; /* 13, 14, 15, 16 */
    assert_false(valid(&r, REG_RESOLUTION, span2, 4));
    assert_false(valid1(&r, REG_BASE_ACCELERATION, 36)); /* B only */
    struct regs rb;
    regs_init(&rb, &board_base);
    assert_true(valid1(&rb, REG_BASE_ACCELERATION, 36));
    assert_false(valid1(&rb, REG_ACCELERATION, 36)); /* not B */
    assert_false(valid1(&rb, REG_DECELERATION, 36));
}

static void write_partial_16_bit_refused(void **state)
{
    (void)state;
    struct regs r;
    regs_init(&r, &board_foot);
    uint8_t d[4] = {0x10, 0x00, 0x20, 0x00};
    assert_true(valid(&r, REG_GOAL_POSITION, d, 2));
    assert_false(valid(&r, REG_GOAL_POSITION, d, 1));            /* low byte only */
    assert_false(valid(&r, REG_GOAL_POSITION + 1, d, 1));        /* high byte only */
    assert_false(valid(&r, REG_GOAL_POSITION + 1, d, 2));        /* straddles two */
    assert_false(valid(&r, REG_GOAL_POSITION, d, 3));            /* + half of speed */
    assert_true(valid(&r, REG_GOAL_POSITION, d, 4));             /* goal and speed */
    assert_false(valid(&r, REG_CCW_LIMIT, d, 1));
    assert_false(valid(&r, REG_CW_LIMIT + 1, d, 2));
}

static void write_cw_above_ccw_refused(void **state)
{
    (void)state;
    struct regs r;
    regs_init(&r, &board_foot); /* CW 0, CCW 360 */
    assert_true(valid2(&r, REG_CW_LIMIT, 360));
    assert_false(valid2(&r, REG_CW_LIMIT, 361));
    assert_true(valid2(&r, REG_CCW_LIMIT, 0));
    regs_set(&r, REG_CW_LIMIT, 100);
    assert_false(valid2(&r, REG_CCW_LIMIT, 99));
    assert_true(valid2(&r, REG_CCW_LIMIT, 100));
    /* Both in one write: judged on the new pair. */
    const uint8_t bad[] = {200, 0, 150, 0};
    assert_false(valid(&r, REG_CW_LIMIT, bad, 4));
    const uint8_t good[] = {0x2C, 0x01, 0x58, 0x02}; /* 300, 600 */
    assert_true(valid(&r, REG_CW_LIMIT, good, 4));
    const uint8_t zero[] = {0, 0, 0, 0}; /* speed mode */
    assert_true(valid(&r, REG_CW_LIMIT, zero, 4));
}

static void write_outside_table_refused(void **state)
{
    (void)state;
    struct regs r;
    regs_init(&r, &board_foot);
    uint8_t d[256];
    memset(d, 0, sizeof d);
    assert_false(valid(&r, REG_ID, d, 0)); /* n = 0 */
    assert_false(valid(&r, REGS_SIZE, d, 1));
    assert_false(valid(&r, 0xFF, d, 1));
    assert_false(valid(&r, REG_MOVE_WITHOUT_REFERENCE, d, 2)); /* 49..50 */
    assert_true(valid(&r, REG_MOVE_WITHOUT_REFERENCE, d, 1));
    assert_false(valid(&r, REG_SLEEP, d, 0xFF));
}

/* ---- regs_read (§4.2) ---------------------------------------------------------- */

static void read_little_endian(void **state)
{
    (void)state;
    struct regs r;
    regs_init(&r, &board_foot);
    regs_set(&r, REG_MOVING_SPEED, 0x1234);
    assert_int_equal(r.mem[REG_MOVING_SPEED], 0x34);
    assert_int_equal(r.mem[REG_MOVING_SPEED + 1], 0x12);
    assert_int_equal(regs_get(&r, REG_MOVING_SPEED), 0x1234);
    uint8_t out[3] = {0xEE, 0xEE, 0xEE};
    regs_read(&r, REG_MOVING_SPEED, 2, out);
    assert_int_equal(out[0], 0x34);
    assert_int_equal(out[1], 0x12);
    assert_int_equal(out[2], 0xEE); /* exactly count bytes */
    regs_read(&r, REG_MOVING_SPEED + 1, 1, out); /* a read may start on the high byte */
    assert_int_equal(out[0], 0x12);
    regs_read(&r, REG_MODEL_NUMBER, 2, out);
    assert_int_equal(out[0], 0x02);
    assert_int_equal(out[1], 0x52);
}

static void read_hidden_addresses_as_zero(void **state)
{
    (void)state;
    struct regs r;
    regs_init(&r, &board_foot);
    /* Put junk everywhere, then check what a READ is allowed to see. */
    memset(r.mem, 0xA7, sizeof r.mem);
    uint8_t out[REGS_SIZE];
    regs_read(&r, 0, REGS_SIZE, out);
    for (size_t i = 0; i < sizeof reserved; i++)
        assert_int_equal(out[reserved[i]], 0);
    assert_int_equal(out[REG_CLEAR_UNLOAD], 0);          /* write-only */
    assert_int_equal(out[REG_PRESENT_POSITION], 0);      /* W, H only */
    assert_int_equal(out[REG_PRESENT_POSITION + 1], 0);
    assert_int_equal(out[REG_BASE_ACCELERATION], 0);     /* B only */
    assert_int_equal(out[REG_BASE_DECELERATION], 0);
    assert_int_equal(out[REG_TURNED_ANGLE], 0xA7);       /* foot has it */
    assert_int_equal(out[REG_TURNED_ANGLE + 1], 0xA7);
    assert_int_equal(out[REG_ACCELERATION], 0xA7);
    assert_int_equal(out[REG_ID], 0xA7);
    /* Reads that start inside a hidden register. */
    uint8_t one = 0xEE;
    regs_read(&r, REG_PRESENT_POSITION + 1, 1, &one);
    assert_int_equal(one, 0);

    struct regs w;
    regs_init(&w, &board_wrist);
    memset(w.mem, 0xA7, sizeof w.mem);
    regs_read(&w, 0, REGS_SIZE, out);
    assert_int_equal(out[REG_TURNED_ANGLE], 0);          /* not W, H */
    assert_int_equal(out[REG_TURNED_ANGLE + 1], 0);
    assert_int_equal(out[REG_PRESENT_POSITION], 0xA7);
    assert_int_equal(out[REG_PRESENT_POSITION + 1], 0xA7);
    one = 0xEE;
    regs_read(&w, REG_TURNED_ANGLE + 1, 1, &one);
    assert_int_equal(one, 0);

    struct regs b;
    regs_init(&b, &board_base);
    memset(b.mem, 0xA7, sizeof b.mem);
    regs_read(&b, 0, REGS_SIZE, out);
    assert_int_equal(out[REG_ACCELERATION], 0);          /* not B */
    assert_int_equal(out[REG_DECELERATION], 0);
    assert_int_equal(out[REG_BASE_ACCELERATION], 0xA7);
}

/* ---- regs_clamp_goal (§4.3, §5.4) -------------------------------------------------- */

static void clamp_goal_to_limits(void **state)
{
    (void)state;
    struct regs r;
    regs_init(&r, &board_foot);
    regs_set(&r, REG_CW_LIMIT, 10);
    regs_set(&r, REG_CCW_LIMIT, 300);
    assert_int_equal(regs_clamp_goal(&r, 0), 10);
    assert_int_equal(regs_clamp_goal(&r, 9), 10);
    assert_int_equal(regs_clamp_goal(&r, 10), 10);
    assert_int_equal(regs_clamp_goal(&r, 150), 150);
    assert_int_equal(regs_clamp_goal(&r, 300), 300);
    assert_int_equal(regs_clamp_goal(&r, 301), 300);
    assert_int_equal(regs_clamp_goal(&r, 0xFFFF), 300);
}

static void clamp_goal_not_in_speed_mode(void **state)
{
    (void)state;
    struct regs r;
    regs_init(&r, &board_foot);
    regs_set(&r, REG_CW_LIMIT, 0);
    regs_set(&r, REG_CCW_LIMIT, 0);
    assert_true(regs_speed_mode(&r));
    assert_int_equal(regs_clamp_goal(&r, 1000), 1000);
    assert_int_equal(regs_clamp_goal(&r, 0xFFFF), 0xFFFF);
    /* The base is always in speed mode: its goal is relative, never clamped. */
    struct regs b;
    regs_init(&b, &board_base);
    regs_set(&b, REG_CCW_LIMIT, 100);
    assert_true(regs_speed_mode(&b));
    assert_int_equal(regs_clamp_goal(&b, 5000), 5000);
}

static void present_position_register_per_variant(void **state)
{
    (void)state;
    struct regs w, f;
    regs_init(&w, &board_wrist);
    regs_init(&f, &board_foot);
    regs_set(&w, REG_PRESENT_POSITION, 123);
    regs_set(&w, REG_TURNED_ANGLE, 7);
    regs_set(&f, REG_PRESENT_POSITION, 7);
    regs_set(&f, REG_TURNED_ANGLE, 321);
    assert_int_equal(regs_present_position(&w), 123);
    assert_int_equal(regs_present_position(&f), 321);
}

/* The invariant the fuzzer and the random-traffic tests check, derived from the table. */
static void first_invalid_register(void **state)
{
    (void)state;
    struct regs r;
    regs_init(&r, &board_arm);
    assert_int_equal(regs_first_invalid(&r), REGS_SIZE);
    r.mem[REG_HOMING] = 0x31; /* status 3 (failed), command 1: valid */
    assert_int_equal(regs_first_invalid(&r), REGS_SIZE);
    r.mem[REG_HOMING] = 0x02; /* command 2 was never accepted */
    assert_int_equal(regs_first_invalid(&r), REG_HOMING);
    regs_init(&r, &board_arm);
    r.mem[REG_STATUS_RETURN_LEVEL] = 3;
    assert_int_equal(regs_first_invalid(&r), REG_STATUS_RETURN_LEVEL);
    regs_init(&r, &board_arm);
    regs_set(&r, REG_CW_LIMIT, 200);
    regs_set(&r, REG_CCW_LIMIT, 100);
    assert_int_equal(regs_first_invalid(&r), REG_CW_LIMIT);
    regs_init(&r, &board_arm);
    r.mem[REG_PRESENT_TEMPERATURE] = 0xFF; /* read-only state: not the host's to break */
    assert_int_equal(regs_first_invalid(&r), REGS_SIZE);
}

/* The bootloader's update mode checks ID, baud and delay without the table
 * (loader_settings): its rules must be exactly the table's ranges and defaults. */
static void loader_rules_are_the_tables(void **state)
{
    (void)state;
    const struct board *const *all = board_all;
    for (uint32_t v = 0; v <= 0xFFFFu; v++) {
        assert_int_equal(regs_in_range(REG_ID, (uint16_t)v), v <= PROTO_ID_MAX);
        assert_int_equal(regs_in_range(REG_RETURN_DELAY, (uint16_t)v), v <= 0xFFu);
        for (uint8_t i = 0; i < BOARD_COUNT; i++)
            assert_int_equal(regs_in_range(REG_BAUD_RATE, (uint16_t)v),
                             v <= 0xFFu && link_baud(all[i], (uint8_t)v) != 0u);
    }
    for (uint8_t i = 0; i < 5u; i++) {
        assert_int_equal(regs_default(all[i], REG_ID), REGS_FACTORY_ID);
        assert_int_equal(regs_default(all[i], REG_BAUD_RATE), 0);
        assert_int_equal(regs_default(all[i], REG_RETURN_DELAY), all[i]->return_delay);
    }
}

/* The store's trigger (issue 19): a writable EEPROM register that gets a different value
 * marks the table; the same value, a RAM register or a read-only one does not. RESET
 * marks only when some stored value was not already factory. */
static void changed_eeprom_values_mark_the_table(void **state)
{
    (void)state;
    struct regs r;
    regs_init(&r, &board_arm);
    assert_false(regs_take_ee_changed(&r)); /* power-up: nothing to store */
    regs_set(&r, REG_TEMPERATURE_LIMIT, regs_get(&r, REG_TEMPERATURE_LIMIT));
    regs_set(&r, REG_GOAL_POSITION, 1234);
    regs_set(&r, REG_PRESENT_SPEED, 77);
    regs_set(&r, REG_MODEL_NUMBER, 1); /* read-only EEPROM: not the store's business */
    assert_false(regs_take_ee_changed(&r));
    regs_set(&r, REG_CCW_LIMIT, (uint16_t)(regs_get(&r, REG_CCW_LIMIT) ^ 0x0100u)); /* high byte */
    assert_true(regs_take_ee_changed(&r));
    assert_false(regs_take_ee_changed(&r)); /* taking clears it */
    regs_init(&r, &board_arm);
    regs_reset(&r); /* already factory: nothing */
    assert_false(regs_take_ee_changed(&r));
    regs_set(&r, REG_ID, 5);
    (void)regs_take_ee_changed(&r);
    regs_reset(&r);
    assert_true(regs_take_ee_changed(&r));
    assert_int_equal(r.mem[REG_ID], REGS_FACTORY_ID);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(changed_eeprom_values_mark_the_table),
        cmocka_unit_test(loader_rules_are_the_tables),
        cmocka_unit_test(first_invalid_register),
        cmocka_unit_test(descriptors_are_sane),
        cmocka_unit_test(sixteen_bit_registers_are_the_specs),
        cmocka_unit_test(no_overlapping_registers),
        cmocka_unit_test(defaults_within_range_on_every_board),
        cmocka_unit_test(reserved_addresses_exist_nowhere),
        cmocka_unit_test(factory_defaults_per_variant),
        cmocka_unit_test(board_defaults_match_section_8),
        cmocka_unit_test(variant_applicability),
        cmocka_unit_test(write_ranges),
        cmocka_unit_test(write_read_only_refused),
        cmocka_unit_test(write_reserved_and_not_applicable_refused),
        cmocka_unit_test(write_partial_16_bit_refused),
        cmocka_unit_test(write_cw_above_ccw_refused),
        cmocka_unit_test(write_outside_table_refused),
        cmocka_unit_test(read_little_endian),
        cmocka_unit_test(read_hidden_addresses_as_zero),
        cmocka_unit_test(clamp_goal_to_limits),
        cmocka_unit_test(clamp_goal_not_in_speed_mode),
        cmocka_unit_test(present_position_register_per_variant),
    };
    return cmocka_run_group_tests(tests, 0, 0);
}
