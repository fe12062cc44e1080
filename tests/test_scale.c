/* test_scale.c - register units and counts (src/scale.c) and the present registers
 * (src/present.c) on their own: every position survives the trip to counts and back at
 * every resolution, speeds are capped at what the reference may ask for, a ramp register
 * of 0 means no ramp, register 38 saturates, and the present registers land where §5
 * puts them on each variant. Links scale.c, present.c, regs.c and the boards. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "planner.h"
#include "present.h"
#include "scale.h"

static void every_position_survives_the_round_trip(void **state)
{
    (void)state;
    for (uint8_t res = 1; res <= 10; res++) {
        struct scale sc = {16384, res};
        for (int32_t u = -0x7FFF; u <= 0x7FFF; u++)
            if (scale_counts_to_units(sc, scale_units_to_counts(sc, u)) != u)
                fail_msg("resolution %u: %d units", res, u);
    }
    struct scale deg = {16384, 10}; /* one unit = 1 degree */
    assert_true(scale_units_to_counts(deg, 360) == 16384);
    assert_true(scale_units_to_counts(deg, -90) == -4096);
}

/* Positions round half away from zero, on both sides of it (a position register reads
 * the same magnitude either side of the zero). */
static void positions_round_half_away_from_zero(void **state)
{
    (void)state;
    struct scale half = {7200, 1}; /* one unit = 0.1 degree = 2 counts */
    const int64_t counts[] = {-3, -2, -1, 0, 1, 2, 3, -4000000001LL, 4000000001LL};
    const int32_t units[] = {-2, -1, -1, 0, 1, 1, 2, -2000000001, 2000000001};
    for (size_t i = 0; i < sizeof counts / sizeof counts[0]; i++)
        assert_int_equal(scale_counts_to_units(half, counts[i]), units[i]);
    struct scale third = {1200, 1}; /* one unit = 1/3 count */
    assert_true(scale_units_to_counts(third, -5) == -2); /* -1.67 */
    assert_true(scale_units_to_counts(third, -4) == -1); /* -1.33 */
    assert_true(scale_units_to_counts(third, 5) == 2);
}

static void speeds_are_capped_and_ramps_of_zero_are_steps(void **state)
{
    (void)state;
    struct scale sc = {16384, 1};
    int32_t max = scale_dps_q24(16384, SCALE_MAX_SPEED_DPS);
    assert_int_equal(scale_speed_q24(sc, 0x7FFF), max); /* 3276.7 deg/s asked: capped */
    assert_int_equal(scale_speed_q24(sc, 3600), scale_dps_q24(16384, 360));
    assert_int_equal(scale_accel_q24(16384, 0, 12345), 12345); /* no ramp: one tick */
    assert_int_equal(scale_accel_q24(16384, 0, 0), 1);
    assert_true(scale_accel_q24(16384, 1, max) >= 1);
    /* 360 deg/s^2 is 16384 counts/s^2, in counts/tick^2 x 2^24 */
    assert_int_equal(scale_accel_q24(16384, 36, max), (int32_t)((16384LL << 24) / 1000000));
}

static void present_speed_reads_units_per_second_and_saturates(void **state)
{
    (void)state;
    struct scale sc = {16384, 10};
    /* 16384 counts/s = 360 deg/s = 360 units/s: 16.384 counts per tick */
    assert_int_equal(scale_speed_units(sc, (int32_t)(16.384 * 256)), 360);
    assert_int_equal(scale_speed_units(sc, 0), 0);
    assert_int_equal(scale_speed_units((struct scale){16384, 1}, INT32_MAX / 4), INT16_MAX);
    assert_int_equal(scale_speed_units((struct scale){16384, 1}, -INT32_MAX / 4), INT16_MIN);
}

static void present_registers_land_where_the_variant_has_them(void **state)
{
    (void)state;
    for (size_t i = 0; i < BOARD_COUNT; i++) {
        struct regs r;
        regs_init(&r, board_all[i]);
        const struct present_inputs in = {1234, -56, true, 2, 254};
        present_write(&r, board_all[i], &in);
        assert_int_equal(regs_get(&r, regs_position_addr(board_all[i])), 1234);
        assert_int_equal((int16_t)regs_get(&r, REG_PRESENT_SPEED), -56);
        assert_int_equal(r.mem[REG_MOVING], 1);
        assert_int_equal(r.mem[REG_PHOTO_SWITCHES], 2);
        assert_int_equal(r.mem[REG_PRESENT_TEMPERATURE], 25); /* 25.4 C */
    }
}

static void temperature_is_rounded_signed_and_clamped(void **state)
{
    (void)state;
    struct regs r;
    regs_init(&r, &board_arm);
    const int16_t dc[] = {0, 4, 5, 255, -4, -5, -123, 1270, 2000, -2000};
    const uint8_t want[] = {0, 0, 1, 26, 0, 0x81, 0x80 | 12, 127, 127, 0x80 | 127};
    for (size_t i = 0; i < sizeof dc / sizeof dc[0]; i++) {
        struct present_inputs in = {0, 0, false, 0, dc[i]};
        present_write(&r, &board_arm, &in);
        assert_int_equal(r.mem[REG_PRESENT_TEMPERATURE], want[i]);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(every_position_survives_the_round_trip),
        cmocka_unit_test(positions_round_half_away_from_zero),
        cmocka_unit_test(speeds_are_capped_and_ramps_of_zero_are_steps),
        cmocka_unit_test(present_speed_reads_units_per_second_and_saturates),
        cmocka_unit_test(present_registers_land_where_the_variant_has_them),
        cmocka_unit_test(temperature_is_rounded_signed_and_clamped),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
