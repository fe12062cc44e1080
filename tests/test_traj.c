/* test_traj.c - TRAJECTORY WRITE decoding and storage (PROTOCOL.md §4.7). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "proto.h"
#include "regs.h"
#include "traj.h"

static struct regs r;
static struct traj t;

static int setup(void **state)
{
    (void)state;
    regs_init(&r, &board_foot); /* limits 0 .. 360 */
    memset(&t, 0, sizeof t);
    return 0;
}

/* A stored trajectory to check refusals against: 3 distinctive points. */
static void store_reference(void)
{
    const uint8_t p[] = {3, 10, 0, 50, 0, 20, 0, 0x34, 0x12, 30, 0, 7, 0};
    assert_int_equal(traj_write(&t, &r, p, sizeof p), 0);
    assert_int_equal(t.count, 3);
}

static void assert_reference(void)
{
    assert_int_equal(t.count, 3);
    assert_int_equal(t.pt[0].angle, 10);
    assert_int_equal(t.pt[0].speed, 50);
    assert_int_equal(t.pt[1].angle, 20);
    assert_int_equal(t.pt[1].speed, 0x1234);
    assert_int_equal(t.pt[2].angle, 30);
    assert_int_equal(t.pt[2].speed, 7);
}

/* A refused write returns an instruction error and leaves the stored points alone. */
static void assert_refused(const uint8_t *p, uint8_t n)
{
    store_reference();
    struct traj before = t;
    assert_int_equal(traj_write(&t, &r, p, n), ERR_INSTRUCTION);
    assert_memory_equal(&before, &t, sizeof t);
    assert_reference();
}

static void four_byte_points(void **state)
{
    (void)state;
    /* VECTORS.md: 2 points, (10, 50) and (20, 50), 4-byte form. */
    const uint8_t p[] = {0x02, 0x0A, 0x00, 0x32, 0x00, 0x14, 0x00, 0x32, 0x00};
    assert_int_equal(traj_write(&t, &r, p, sizeof p), 0);
    assert_int_equal(t.count, 2);
    assert_int_equal(t.pt[0].angle, 10);
    assert_int_equal(t.pt[0].speed, 50);
    assert_int_equal(t.pt[1].angle, 20);
    assert_int_equal(t.pt[1].speed, 50);
    /* Little-endian 16-bit angle and speed. */
    const uint8_t q[] = {0x01, 0x2C, 0x01, 0x90, 0x01};
    assert_int_equal(traj_write(&t, &r, q, sizeof q), 0);
    assert_int_equal(t.count, 1);
    assert_int_equal(t.pt[0].angle, 300);
    assert_int_equal(t.pt[0].speed, 400);
}

static void three_byte_points(void **state)
{
    (void)state;
    const uint8_t p[] = {0x02, 0x0A, 0x00, 0x32, 0x14, 0x00, 0x32};
    assert_int_equal(traj_write(&t, &r, p, sizeof p), 0);
    assert_int_equal(t.count, 2);
    assert_int_equal(t.pt[0].angle, 10);
    assert_int_equal(t.pt[0].speed, 50);
    assert_int_equal(t.pt[1].angle, 20);
    assert_int_equal(t.pt[1].speed, 50);
    const uint8_t q[] = {0x01, 0x2C, 0x01, 0xFF};
    assert_int_equal(traj_write(&t, &r, q, sizeof q), 0);
    assert_int_equal(t.count, 1);
    assert_int_equal(t.pt[0].angle, 300);
    assert_int_equal(t.pt[0].speed, 255);
}

/* 12 bytes of points: 4 points of 3 or 3 points of 4 - count decides. */
static void point_size_follows_from_count(void **state)
{
    (void)state;
    const uint8_t p4[] = {3, 1, 0, 2, 0, 3, 0, 4, 0, 5, 0, 6, 0};
    assert_int_equal(traj_write(&t, &r, p4, sizeof p4), 0);
    assert_int_equal(t.count, 3);
    assert_int_equal(t.pt[2].angle, 5);
    assert_int_equal(t.pt[2].speed, 6);
    const uint8_t p3[] = {4, 1, 0, 2, 3, 0, 4, 5, 0, 6, 7, 0, 8};
    assert_int_equal(traj_write(&t, &r, p3, sizeof p3), 0);
    assert_int_equal(t.count, 4);
    assert_int_equal(t.pt[3].angle, 7);
    assert_int_equal(t.pt[3].speed, 8);
}

static void write_replaces_stored_trajectory(void **state)
{
    (void)state;
    store_reference();
    const uint8_t p[] = {1, 100, 0, 9};
    assert_int_equal(traj_write(&t, &r, p, sizeof p), 0);
    assert_int_equal(t.count, 1);
    assert_int_equal(t.pt[0].angle, 100);
    assert_int_equal(t.pt[0].speed, 9);
    /* The same packet again (a repeat after a lost answer) does no harm. */
    assert_int_equal(traj_write(&t, &r, p, sizeof p), 0);
    assert_int_equal(t.count, 1);
    assert_int_equal(t.pt[0].angle, 100);
}

static void count_zero_clears(void **state)
{
    (void)state;
    store_reference();
    const uint8_t p[] = {0};
    assert_int_equal(traj_write(&t, &r, p, 1), 0);
    assert_int_equal(t.count, 0);
    store_reference();
    traj_clear(&t);
    assert_int_equal(t.count, 0);
}

static void count_zero_with_points_refused(void **state)
{
    (void)state;
    const uint8_t p[] = {0, 10, 0, 5};
    assert_refused(p, sizeof p);
}

static void no_parameters_refused(void **state)
{
    (void)state;
    const uint8_t p[] = {0};
    assert_refused(p, 0);
}

static void mismatched_length_refused(void **state)
{
    (void)state;
    const uint8_t p[] = {2, 10, 0, 50, 0, 20, 0, 50, 0, 0xAA};
    assert_refused(p, 8);  /* 7 bytes for 2 points */
    assert_refused(p, 10); /* 9 bytes for 2 points */
    assert_refused(p, 5);  /* 4 bytes for 2 points: 2 each */
    assert_refused(p, 1);  /* count 2, no points */
    const uint8_t q[] = {3, 1, 0, 1, 2, 0, 1, 3, 0, 1, 4, 0};
    assert_refused(q, sizeof q); /* 11 bytes for 3 points */
    const uint8_t big[] = {200, 1, 0, 1};
    assert_refused(big, sizeof big);
}

static void point_size_5_refused(void **state)
{
    (void)state;
    const uint8_t p[] = {2, 10, 0, 50, 0, 0, 20, 0, 50, 0, 0};
    assert_refused(p, 6);  /* 1 point of 5 */
    assert_refused(p, 11); /* 2 points of 5 */
    const uint8_t q[] = {1, 10, 0};
    assert_refused(q, sizeof q); /* 1 point of 2 */
    const uint8_t s6[] = {1, 10, 0, 5, 0, 0, 0};
    assert_refused(s6, sizeof s6); /* 1 point of 6 */
}

static void speed_zero_refused(void **state)
{
    (void)state;
    const uint8_t p4[] = {2, 10, 0, 50, 0, 20, 0, 0, 0};
    assert_refused(p4, sizeof p4); /* last point */
    const uint8_t p4a[] = {2, 10, 0, 0, 0, 20, 0, 50, 0};
    assert_refused(p4a, sizeof p4a); /* first point */
    const uint8_t p3[] = {3, 10, 0, 5, 20, 0, 0, 30, 0, 5};
    assert_refused(p3, sizeof p3); /* middle point */
    /* 0x0100 is not zero: only the high byte set. */
    const uint8_t hi[] = {1, 10, 0, 0x00, 0x01};
    assert_int_equal(traj_write(&t, &r, hi, sizeof hi), 0);
    assert_int_equal(t.pt[0].speed, 0x100);
}

static void angles_clamped_to_limits(void **state)
{
    (void)state;
    regs_set(&r, REG_CW_LIMIT, 20);
    regs_set(&r, REG_CCW_LIMIT, 300);
    const uint8_t p[] = {4, 5, 0, 9, 0x2C, 0x01, 9, 0xFF, 0xFF, 9, 150, 0, 9};
    assert_int_equal(traj_write(&t, &r, p, sizeof p), 0);
    assert_int_equal(t.count, 4);
    assert_int_equal(t.pt[0].angle, 20);
    assert_int_equal(t.pt[1].angle, 300);
    assert_int_equal(t.pt[2].angle, 300);
    assert_int_equal(t.pt[3].angle, 150);
}

static void most_points_of_one_packet_fit(void **state)
{
    (void)state;
    /* LEN 255 carries 253 parameters: count + 84 points of 3, or count + 63 of 4. */
    assert_true(TRAJ_POINTS_MAX >= 84u);
    uint8_t p[253];
    p[0] = 84;
    for (uint8_t i = 0; i < 84; i++) {
        uint16_t a = (uint16_t)(i * 4u);
        p[1 + 3 * i] = (uint8_t)a;
        p[2 + 3 * i] = (uint8_t)(a >> 8);
        p[3 + 3 * i] = (uint8_t)(i + 1u);
    }
    assert_int_equal(traj_write(&t, &r, p, sizeof p), 0);
    assert_int_equal(t.count, 84);
    for (uint8_t i = 0; i < 84; i++) {
        assert_int_equal(t.pt[i].angle, i * 4u);
        assert_int_equal(t.pt[i].speed, i + 1u);
    }
    p[0] = 63;
    for (uint8_t i = 0; i < 63; i++) {
        uint16_t a = (uint16_t)(359u - i);
        uint16_t s = (uint16_t)(1000u + i * 300u);
        p[1 + 4 * i] = (uint8_t)a;
        p[2 + 4 * i] = (uint8_t)(a >> 8);
        p[3 + 4 * i] = (uint8_t)s;
        p[4 + 4 * i] = (uint8_t)(s >> 8);
    }
    assert_int_equal(traj_write(&t, &r, p, sizeof p), 0);
    assert_int_equal(t.count, 63);
    for (uint8_t i = 0; i < 63; i++) {
        assert_int_equal(t.pt[i].angle, 359u - i);
        assert_int_equal(t.pt[i].speed, 1000u + i * 300u);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(four_byte_points, setup),
        cmocka_unit_test_setup(three_byte_points, setup),
        cmocka_unit_test_setup(point_size_follows_from_count, setup),
        cmocka_unit_test_setup(write_replaces_stored_trajectory, setup),
        cmocka_unit_test_setup(count_zero_clears, setup),
        cmocka_unit_test_setup(count_zero_with_points_refused, setup),
        cmocka_unit_test_setup(no_parameters_refused, setup),
        cmocka_unit_test_setup(mismatched_length_refused, setup),
        cmocka_unit_test_setup(point_size_5_refused, setup),
        cmocka_unit_test_setup(speed_zero_refused, setup),
        cmocka_unit_test_setup(angles_clamped_to_limits, setup),
        cmocka_unit_test_setup(most_points_of_one_packet_fit, setup),
    };
    return cmocka_run_group_tests(tests, 0, 0);
}
