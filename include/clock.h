/* clock.h - wrap-safe arithmetic on the 32-bit microsecond clock (hal_clock_us()).
 *
 * The clock wraps every 2^32 us, 71.6 min. Every comparison of two instants in the core
 * goes through these two, in the style of the Linux kernel's time_after(): a plain
 * `now >= deadline` breaks at the wrap, and a signed difference breaks when the two are
 * more than 35.8 min apart. The host clock starts 10 s before the wrap
 * (HAL_HOST_CLOCK_START), so every test crosses it.
 *
 * An interval longer than 71.6 min cannot be measured by one difference: a caller that
 * may wait that long (the commit budget's refill after a long idle) looks at the clock
 * every main-loop pass and counts in steps, saturating. */
#ifndef CLOCK_H
#define CLOCK_H

#include <stdbool.h>
#include <stdint.h>

/* Has now reached t? Both within 35.8 min of each other (a deadline set recently). */
static inline bool clock_reached(uint32_t now, uint32_t t)
{
    return (int32_t)(now - t) >= 0;
}

/* Microseconds from then to now; exact while they are less than 71.6 min apart. */
static inline uint32_t clock_since(uint32_t now, uint32_t then)
{
    return now - then;
}

#endif
