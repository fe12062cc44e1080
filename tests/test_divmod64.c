/* test_divmod64.c - the application image's 64-bit division (hal/stm32f1/divmod64.c) gives
 * C's quotient and remainder: every path (32-bit operands, 64-bit dividend over a 32-bit
 * divisor, both 64-bit, the sign cases) against the host compiler's own `/` and `%`. A
 * wrong bit here would move a servo to the wrong place, so it is checked exhaustively on
 * the edges and on a million random pairs. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "divmod64.h"

static uint64_t rng_state = 0x9E3779B97F4A7C15u;

static uint64_t rnd(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return rng_state;
}

/* A value of a random width, so every path is taken often. */
static uint64_t rnd_width(void)
{
    uint32_t bits = (uint32_t)(rnd() % 64u) + 1u;
    return rnd() >> (64u - bits);
}

static void check_u(uint64_t n, uint64_t d)
{
    struct divmod64 io = {n, d};
    divmod64_unsigned(&io);
    if (io.num != n / d || io.den != n % d)
        fail_msg("%llu / %llu: got %llu r %llu", (unsigned long long)n, (unsigned long long)d,
                 (unsigned long long)io.num, (unsigned long long)io.den);
}

static void check_s(int64_t n, int64_t d)
{
    if (n == INT64_MIN && d == -1)
        return; /* overflows in C as well */
    struct divmod64 io = {(uint64_t)n, (uint64_t)d};
    divmod64_signed(&io);
    if ((int64_t)io.num != n / d || (int64_t)io.den != n % d)
        fail_msg("%lld / %lld: got %lld r %lld", (long long)n, (long long)d, (long long)io.num,
                 (long long)io.den);
}

static void edges_match_c(void **state)
{
    (void)state;
    const uint64_t v[] = {1, 2, 3, 7, 255, 256, 3600, 0x7FFFFFFFu, 0x80000000u, 0xFFFFFFFFu,
                          0x100000000u, 0x100000001u, 0x7FFFFFFFFFFFFFFFu,
                          0x8000000000000000u, 0xFFFFFFFFFFFFFFFFu, 0xFFFFFFFF00000000u};
    for (size_t i = 0; i < sizeof v / sizeof v[0]; i++)
        for (size_t j = 0; j < sizeof v / sizeof v[0]; j++) {
            check_u(v[i], v[j]);
            check_s((int64_t)v[i], (int64_t)v[j]);
            check_s(-(int64_t)(v[i] >> 1), (int64_t)v[j]);
        }
    check_u(0, 5);
    check_s(0, -5);
}

static void random_pairs_match_c(void **state)
{
    (void)state;
    for (uint32_t i = 0; i < 1000000u; i++) {
        uint64_t n = rnd_width(), d = rnd_width();
        if (d == 0u)
            d = 1;
        check_u(n, d);
        check_s((int64_t)n * ((rnd() & 1u) ? -1 : 1), (int64_t)(d >> 1 | 1u) * ((rnd() & 1u) ? -1 : 1));
    }
}

static void zero_divisor_is_defined(void **state)
{
    (void)state;
    struct divmod64 io = {1234, 0};
    divmod64_unsigned(&io);
    assert_true(io.num == UINT64_MAX && io.den == 1234u);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(edges_match_c),
        cmocka_unit_test(random_pairs_match_c),
        cmocka_unit_test(zero_divisor_is_defined),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
