/* test_crc.c - the two checks of crc.h as their users rely on them: the CRC-32 that
 * decides whether the bootloader starts an image (and which a host computes over the
 * update file with any standard tool), the CRC-16/XMODEM of a §10 data block that a
 * host's YMODEM sender computes, and the CRC-16/CCITT-FALSE of the store's records.
 * Each against the published check values and against a bit-at-a-time model written
 * here from the polynomials' definitions, not from src/crc.c. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "crc.h"
#include "model_crc.h"

static const uint8_t check_string[] = "123456789";

/* CRC-16, polynomial 0x1021, most significant bit first, no final xor. */
static uint16_t model_crc16(uint16_t crc, const uint8_t *p, uint32_t n)
{
    for (uint32_t i = 0; i < n; i++) {
        crc ^= (uint16_t)(p[i] << 8);
        for (int b = 0; b < 8; b++)
            crc = (uint16_t)((crc & 0x8000u) ? ((uint32_t)crc << 1) ^ 0x1021u
                                             : (uint32_t)crc << 1);
    }
    return crc;
}

static uint32_t rng = 12345u;
static uint8_t rnd8(void)
{
    rng = rng * 1103515245u + 12345u;
    return (uint8_t)(rng >> 16);
}

/* The catalogue's check values: what zlib, crc32(1), Python's binascii and YMODEM
 * senders compute. A host tool stamping or checking an update file gets the same. */
static void crcs_match_the_published_check_values(void **state)
{
    (void)state;
    assert_int_equal(~crc32_update(CRC32_INIT, check_string, 9), 0xCBF43926u);
    assert_int_equal(crc16_update(0, check_string, 9), 0x31C3u);      /* XMODEM, §10 */
    assert_int_equal(crc16_update(0xFFFFu, check_string, 9), 0x29B1u); /* CCITT-FALSE */
    assert_int_equal(~crc32_update(CRC32_INIT, check_string, 0), 0u); /* nothing fed */
}

/* A whole application slot's worth of bytes, fed in pieces of every size the callers
 * use (a page, a block, the three parts around the info block's CRC field): the same
 * result as the model over the bytes at once. */
static void crc32_of_an_image_fed_in_pieces_equals_the_model(void **state)
{
    (void)state;
    enum { LEN = 26 * 1024 };
    static uint8_t img[LEN];
    for (uint32_t i = 0; i < LEN; i++)
        img[i] = rnd8();
    uint32_t want = model_crc32(img, LEN);
    assert_int_equal(~crc32_update(CRC32_INIT, img, LEN), want);
    static const uint32_t pieces[] = {1, 3, 8, 264, 1024};
    for (size_t k = 0; k < sizeof pieces / sizeof pieces[0]; k++) {
        uint32_t crc = CRC32_INIT;
        for (uint32_t done = 0; done < LEN;) {
            uint32_t n = LEN - done < pieces[k] ? LEN - done : pieces[k];
            crc = crc32_update(crc, &img[done], n);
            done += n;
        }
        assert_int_equal(~crc, want);
    }
}

/* Any one flipped bit of an image, anywhere, changes its CRC-32: the bootloader never
 * starts an image damaged by one bit (in transit, or a half-programmed flash word). */
static void crc32_catches_every_single_bit_flip_of_a_16_kib_image(void **state)
{
    (void)state;
    enum { LEN = 16 * 1024 };
    static uint8_t img[LEN];
    for (uint32_t i = 0; i < LEN; i++)
        img[i] = rnd8();
    uint32_t good = crc32_update(CRC32_INIT, img, LEN);
    for (uint32_t i = 0; i < LEN; i += 97u) {
        for (uint8_t b = 0; b < 8u; b++) {
            img[i] ^= (uint8_t)(1u << b);
            assert_int_not_equal(crc32_update(CRC32_INIT, img, LEN), good);
            img[i] ^= (uint8_t)(1u << b);
        }
    }
}

/* §10 data blocks (1024 bytes) and store records (4 bytes) with random contents: the
 * CRC-16 equals the model from both starting values, and catches any one or two flipped
 * bits of a store record, whatever its contents. */
static void crc16_of_blocks_and_records_equals_the_model(void **state)
{
    (void)state;
    uint8_t block[1024];
    for (int round = 0; round < 50; round++) {
        for (size_t i = 0; i < sizeof block; i++)
            block[i] = rnd8();
        assert_int_equal(crc16_update(0, block, sizeof block), model_crc16(0, block, sizeof block));
        assert_int_equal(crc16_update(0xFFFFu, block, 4), model_crc16(0xFFFFu, block, 4));
        uint16_t good = crc16_update(0xFFFFu, block, 4);
        for (uint32_t a = 0; a < 32u; a++)
            for (uint32_t b = a; b < 32u; b++) {
                uint8_t rec[4];
                memcpy(rec, block, 4);
                rec[a / 8u] ^= (uint8_t)(1u << (a % 8u));
                if (b != a)
                    rec[b / 8u] ^= (uint8_t)(1u << (b % 8u));
                assert_int_not_equal(crc16_update(0xFFFFu, rec, 4), good);
            }
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(crcs_match_the_published_check_values),
        cmocka_unit_test(crc32_of_an_image_fed_in_pieces_equals_the_model),
        cmocka_unit_test(crc32_catches_every_single_bit_flip_of_a_16_kib_image),
        cmocka_unit_test(crc16_of_blocks_and_records_equals_the_model),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
