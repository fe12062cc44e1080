/* test_image.c - what makes a flash slot an image the bootloader starts (image.h), as a
 * user meets it: the update file `make firmware` stamps (magic, length, CRC-32 with its
 * own field read as 0, model, version) is valid for its own board only, and any damage
 * or a length outside the slot makes it invalid; a page written by the update session
 * holds exactly its bytes, never the install mark. Images are stamped here with a CRC-32
 * written from its definition, as tools/fwstamp.py (Python's zlib) does, not with
 * src/crc.c. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "board.h"
#include "hal_host.h"
#include "image.h"
#include "model_crc.h"

static struct hal hal;
static uint8_t img[IMAGE_MAX_BYTES];

static void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

/* An update file as make firmware writes it: len bytes, the info block filled in, then
 * the CRC-32 of the whole with the CRC field 0 written into that field. */
static void stamp(uint32_t len, uint16_t model, uint8_t version, uint32_t seed)
{
    for (uint32_t i = 0; i < len; i++) {
        seed = seed * 1103515245u + 12345u;
        img[i] = (uint8_t)(seed >> 16);
    }
    uint8_t *info = &img[IMAGE_INFO_OFFSET];
    put32(&info[IMAGE_OFF_MAGIC], IMAGE_MAGIC);
    put32(&info[IMAGE_OFF_LENGTH], len);
    put32(&info[IMAGE_OFF_CRC], 0);
    info[IMAGE_OFF_MODEL] = (uint8_t)model;
    info[IMAGE_OFF_MODEL + 1] = (uint8_t)(model >> 8);
    info[IMAGE_OFF_VERSION] = version;
    info[IMAGE_OFF_RESERVED] = 0;
    put32(&info[IMAGE_OFF_CRC], model_crc32(img, len));
}

/* Program img (len bytes) into the application slot as a programmer does. */
static void flash_app(uint32_t len)
{
    hal_host_init(&hal);
    hal_host_program_app(&hal, img, len);
}

static bool app_valid(uint16_t model, struct image_info *info)
{
    return image_valid(&hal, HAL_PAGE_APP, model, info);
}

/* The stamped file is a valid image for its own board, of every board and of lengths
 * from the smallest to the whole slot, and its info block reads back as stamped. */
static void a_stamped_image_is_valid_for_its_board(void **state)
{
    (void)state;
    static const uint32_t lengths[] = {IMAGE_MIN_BYTES, IMAGE_MIN_BYTES + 2u, 1024u, 1025u,
                                       16u * 1024u, IMAGE_MAX_BYTES};
    for (uint32_t b = 0; b < BOARD_COUNT; b++)
        for (size_t k = 0; k < sizeof lengths / sizeof lengths[0]; k++) {
            uint16_t model = board_all[b]->model_number;
            stamp(lengths[k], model, (uint8_t)(k + 1u), b * 10u + (uint32_t)k);
            flash_app(lengths[k]);
            struct image_info info;
            assert_true(app_valid(model, &info));
            assert_int_equal(info.length, lengths[k]);
            assert_int_equal(info.model, model);
            assert_int_equal(info.version, k + 1u);
            assert_int_equal(image_crc(&hal, HAL_PAGE_APP, lengths[k]), info.crc);
        }
}

/* Another board's image is never started: the arm's firmware in a finger is refused. */
static void another_boards_image_is_invalid(void **state)
{
    (void)state;
    stamp(8000, BOARD_MODEL_ARM, 1, 7);
    flash_app(8000);
    for (uint32_t b = 0; b < BOARD_COUNT; b++)
        assert_int_equal(app_valid(board_all[b]->model_number, NULL),
                         board_all[b]->model_number == BOARD_MODEL_ARM);
}

/* One damaged byte anywhere in the image (its code, its info block, its last byte) makes
 * it invalid; a byte past its length, which the CRC does not cover, does not. */
static void a_damaged_byte_anywhere_makes_it_invalid(void **state)
{
    (void)state;
    const uint32_t len = 5000;
    static const uint32_t at[] = {0, 1, IMAGE_INFO_OFFSET - 1u,
                                  IMAGE_INFO_OFFSET + IMAGE_OFF_CRC,
                                  IMAGE_INFO_OFFSET + IMAGE_OFF_VERSION,
                                  IMAGE_INFO_OFFSET + IMAGE_OFF_RESERVED, 1023, 1024, 4999};
    for (size_t k = 0; k < sizeof at / sizeof at[0]; k++) {
        stamp(len, BOARD_MODEL_FOOT, 3, 99);
        img[at[k]] ^= 0x10u;
        flash_app(len);
        assert_false(app_valid(BOARD_MODEL_FOOT, NULL));
    }
    stamp(len, BOARD_MODEL_FOOT, 3, 99);
    img[len] = 0x5A; /* past the image: padding of the last page */
    flash_app(len + 2u);
    assert_true(app_valid(BOARD_MODEL_FOOT, NULL));
}

/* Wrong magic, a length below the info block's end or past the slot (even with a right
 * CRC-32 over what is there), or an erased slot: invalid. */
static void wrong_magic_length_or_an_erased_slot_is_invalid(void **state)
{
    (void)state;
    hal_host_init(&hal);
    assert_false(app_valid(BOARD_MODEL_ARM, NULL)); /* erased */
    stamp(3000, BOARD_MODEL_ARM, 1, 5);
    img[IMAGE_INFO_OFFSET + IMAGE_OFF_MAGIC] ^= 1u;
    put32(&img[IMAGE_INFO_OFFSET + IMAGE_OFF_CRC], 0);
    put32(&img[IMAGE_INFO_OFFSET + IMAGE_OFF_CRC], model_crc32(img, 3000));
    flash_app(3000);
    assert_false(app_valid(BOARD_MODEL_ARM, NULL));
    static const uint32_t bad_len[] = {IMAGE_MIN_BYTES - 1u, 0, IMAGE_MAX_BYTES + 1u,
                                       0xFFFFFFFFu};
    for (size_t k = 0; k < sizeof bad_len / sizeof bad_len[0]; k++) {
        stamp(3000, BOARD_MODEL_ARM, 1, 5);
        put32(&img[IMAGE_INFO_OFFSET + IMAGE_OFF_LENGTH], bad_len[k]);
        put32(&img[IMAGE_INFO_OFFSET + IMAGE_OFF_CRC], 0);
        uint32_t n = bad_len[k] < 3000u ? bad_len[k] : 3000u;
        put32(&img[IMAGE_INFO_OFFSET + IMAGE_OFF_CRC], model_crc32(img, n));
        flash_app(3000);
        struct image_info info;
        assert_false(image_parse_info(hal_flash_page(&hal, HAL_PAGE_APP), &info));
        assert_false(app_valid(BOARD_MODEL_ARM, NULL));
    }
}

/* A page the update session writes holds its bytes and nothing else: the rest of the
 * page stays erased, so a last block's padding never reaches the install mark; the mark
 * reads set only once programmed to 0. A failed program (a power cut) reports false. */
static void a_written_page_holds_its_bytes_and_never_the_install_mark(void **state)
{
    (void)state;
    hal_host_init(&hal);
    uint8_t data[HAL_FLASH_PAGE_BYTES];
    for (size_t i = 0; i < sizeof data; i++)
        data[i] = (uint8_t)(i * 7u + 1u);
    data[10] = 0xFF; /* a half-word of 0xFFFF is left erased, not programmed */
    data[11] = 0xFF;
    assert_true(image_write_page(&hal, IMAGE_MARK_PAGE, data, 200));
    const uint8_t *page = hal_flash_page(&hal, IMAGE_MARK_PAGE);
    assert_memory_equal(page, data, 200);
    for (uint32_t i = 200; i < HAL_FLASH_PAGE_BYTES; i++)
        assert_int_equal(page[i], 0xFF);
    assert_false(image_marked(&hal));
    assert_true(hal_flash_program(&hal, IMAGE_MARK_PAGE, IMAGE_MARK_OFFSET, IMAGE_MARK_SET));
    assert_true(image_marked(&hal));
    assert_true(image_write_page(&hal, IMAGE_MARK_PAGE, data, 200)); /* erases it again */
    assert_false(image_marked(&hal));

    hal.flash.cut_at = hal.flash.ops + 5u; /* the power goes during the page's programs */
    assert_false(image_write_page(&hal, HAL_PAGE_STAGING, data, sizeof data));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_stamped_image_is_valid_for_its_board),
        cmocka_unit_test(another_boards_image_is_invalid),
        cmocka_unit_test(a_damaged_byte_anywhere_makes_it_invalid),
        cmocka_unit_test(wrong_magic_length_or_an_erased_slot_is_invalid),
        cmocka_unit_test(a_written_page_holds_its_bytes_and_never_the_install_mark),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
