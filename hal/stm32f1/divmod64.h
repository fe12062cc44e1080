/* divmod64.h - 64-bit division for the application image, in place of libgcc's. */
#ifndef DIVMOD64_H
#define DIVMOD64_H

#include <stdint.h>

/* In: num / den. Out: num holds the quotient, den the remainder (C's rules: the quotient
 * truncated toward 0, the remainder with the sign of the dividend). A zero divisor gives
 * the quotient ~0 and the remainder num; the firmware never divides by zero. The layout is
 * that of r0-r3 at an __aeabi_[u]ldivmod call, which the wrappers in divmod64.c rely on. */
struct divmod64 {
    uint64_t num;
    uint64_t den;
};

void divmod64_unsigned(struct divmod64 *io);
void divmod64_signed(struct divmod64 *io); /* num and den hold int64_t values */

#endif
