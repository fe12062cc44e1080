/* proto.c - checksum and status packet encoding (PROTOCOL.md §2, §3). */
#include <string.h>

#include "proto.h"

uint16_t proto_get16(const uint8_t *p)
{
#if __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    /* One halfword load: the Cortex-M3 loads unaligned halfwords, and this is inlined in
     * some twenty places (about 100 B less than two byte loads). */
    uint16_t v;
    /* cppcheck-suppress misra-c2012-21.15 ; bytes into a half-word, on purpose (docs/lint.md) */
    memcpy(&v, p, sizeof v);
    return v;
#else
    return (uint16_t)(p[0] + 256u * p[1]);
#endif
}

uint32_t proto_get32(const uint8_t *p)
{
#if __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    /* One word load: the Cortex-M3 loads unaligned words with LDR (only LDRD, LDM and
     * the exclusive loads fault, which a 4-byte copy never becomes), and the port leaves
     * CCR.UNALIGN_TRP at its reset value, clear. */
    uint32_t v;
    __builtin_memcpy(&v, p, sizeof v);
    return v;
#else
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
#endif
}

uint8_t proto_sum(const uint8_t *p, uint16_t n)
{
    uint8_t sum = 0;
    while (n--)
        sum = (uint8_t)(sum + *p++);
    return sum;
}

uint16_t proto_build_packet(uint8_t *out, uint8_t id, uint8_t first, const uint8_t *data,
                            uint8_t n)
{
    out[0] = PROTO_HEADER0;
    out[1] = PROTO_HEADER1;
    out[2] = id;
    out[3] = (uint8_t)(n + 2u);
    out[4] = first;
    if (n)
        memcpy(&out[5], data, n);
    out[5u + n] = proto_sum(&out[2], (uint16_t)(n + 3u));
    return (uint16_t)(n + 6u);
}

bool proto_speed_is_stop(uint16_t speed)
{
    return (speed & PROTO_SPEED_MAGNITUDE) == 0u;
}
