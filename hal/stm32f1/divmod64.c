/* divmod64.c - the application's 64-bit division. libgcc's __aeabi_ldivmod and
 * __aeabi_uldivmod bring in __udivmoddi4: about 900 B, a twentieth of the 16 KiB goal.
 * The motion layer divides 64-bit values in a few places per tick, and most operands fit
 * 32 bits, where the Cortex-M3's UDIV answers in one instruction; a 64-bit dividend
 * over a 32-bit divisor takes one hardware division and 32 shift-subtract steps. Exact:
 * the same quotient and remainder as C's `/` and `%` (tests/test_divmod64.c compares
 * them on the host). Runs in the main loop only (nothing in interrupt context divides
 * 64-bit numbers: check_isr_ram.py would see the call). */
#include "divmod64.h"

/* (hi:lo) / d where hi < d: the quotient fits 32 bits. */
static uint32_t div_steps(uint64_t *rem, uint32_t lo, uint32_t d)
{
    uint64_t r = *rem;
    uint32_t q = 0;
    for (int32_t i = 31; i >= 0; i--) {
        r = (r << 1) | ((lo >> (uint32_t)i) & 1u); /* r < 2d < 2^33: no overflow */
        q <<= 1;
        if (r >= d) {
            r -= d;
            q |= 1u;
        }
    }
    *rem = r;
    return q;
}

void divmod64_unsigned(struct divmod64 *io)
{
    uint64_t n = io->num, d = io->den;
    if (d == 0u) {
        io->num = UINT64_MAX;
        io->den = n;
    } else if (n < d) {
        io->num = 0;
        io->den = n;
    } else if ((n >> 32) == 0u) { /* then d < 2^32 too */
        uint32_t q = (uint32_t)n / (uint32_t)d;
        io->num = q;
        io->den = (uint32_t)n - q * (uint32_t)d;
    } else if ((d >> 32) == 0u) {
        uint32_t d32 = (uint32_t)d;
        uint32_t hi = (uint32_t)(n >> 32);
        uint32_t qhi = hi / d32;
        uint64_t rem = hi - qhi * d32;
        uint32_t qlo = div_steps(&rem, (uint32_t)n, d32);
        io->num = ((uint64_t)qhi << 32) | qlo;
        io->den = rem;
    } else { /* both 64-bit: the quotient fits 32 bits, one bit at a time */
        uint64_t q = 0, r = n;
        uint32_t shift = 0;
        while (!(d >> 63) && (d << 1) <= r) {
            d <<= 1;
            shift++;
        }
        for (;;) {
            q <<= 1;
            if (r >= d) {
                r -= d;
                q |= 1u;
            }
            if (shift-- == 0u)
                break;
            d >>= 1;
        }
        io->num = q;
        io->den = r;
    }
}

void divmod64_signed(struct divmod64 *io)
{
    int neg_n = (int64_t)io->num < 0, neg_d = (int64_t)io->den < 0;
    if (neg_n)
        io->num = 0u - io->num;
    if (neg_d)
        io->den = 0u - io->den;
    divmod64_unsigned(io);
    if (neg_n != neg_d)
        io->num = 0u - io->num;
    if (neg_n)
        io->den = 0u - io->den;
}

#if defined(__arm__)
/* The run-time ABI's entry points (ARM IHI 0043): dividend in r0:r1, divisor in r2:r3,
 * quotient back in r0:r1 and remainder in r2:r3. Pushing r0-r3 lays out a struct divmod64
 * on the stack (8-byte aligned: six words), which the C code rewrites in place. */
void __aeabi_uldivmod(void);
void __aeabi_ldivmod(void);

__attribute__((naked, used)) void __aeabi_uldivmod(void)
{
    __asm volatile("push {r0, r1, r2, r3, r4, lr}\n\t"
                   "mov r0, sp\n\t"
                   "bl divmod64_unsigned\n\t"
                   "pop {r0, r1, r2, r3, r4, pc}\n\t");
}

__attribute__((naked, used)) void __aeabi_ldivmod(void)
{
    __asm volatile("push {r0, r1, r2, r3, r4, lr}\n\t"
                   "mov r0, sp\n\t"
                   "bl divmod64_signed\n\t"
                   "pop {r0, r1, r2, r3, r4, pc}\n\t");
}
#endif
