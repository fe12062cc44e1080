/* test_rng.h - the tests' one pseudo-random generator: Marsaglia's xorshift32 (13, 17, 5),
 * its state kept by each test and seeded by it, so a failure's seed replays it. Not for
 * the firmware (which has no randomness). */
#ifndef TEST_RNG_H
#define TEST_RNG_H

#include <stdint.h>

/* The next value of the sequence; *state must not be 0. */
static inline uint32_t xorshift32(uint32_t *state)
{
    uint32_t x = *state;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    return *state = x;
}

#endif
