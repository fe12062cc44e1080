/* image.c - the validity check of an image in a flash slot (image.h). */
#include <string.h>

#include "crc.h"
#include "image.h"
#include "proto.h"

bool image_parse_info(const uint8_t *page0, struct image_info *out)
{
    const uint8_t *info = &page0[IMAGE_INFO_OFFSET];
    out->length = proto_get32(&info[IMAGE_OFF_LENGTH]);
    out->crc = proto_get32(&info[IMAGE_OFF_CRC]);
    out->model = proto_get16(&info[IMAGE_OFF_MODEL]);
    out->version = info[IMAGE_OFF_VERSION];
    return proto_get32(&info[IMAGE_OFF_MAGIC]) == IMAGE_MAGIC && out->length >= IMAGE_MIN_BYTES &&
           out->length <= IMAGE_MAX_BYTES;
}

uint32_t image_crc(struct hal *hal, uint8_t first_page, uint32_t length)
{
    static const uint8_t zero[4];
    const uint32_t crc_at = IMAGE_INFO_OFFSET + IMAGE_OFF_CRC;
    uint32_t crc = CRC32_INIT;
    for (uint32_t done = 0; done < length;) {
        const uint8_t *page = hal_flash_page(hal, (uint8_t)(first_page + done / HAL_FLASH_PAGE_BYTES));
        uint32_t n = length - done < HAL_FLASH_PAGE_BYTES ? length - done : HAL_FLASH_PAGE_BYTES;
        if (done == 0u) { /* the first page holds the crc field: read it as zeros */
            crc = crc32_update(crc, page, crc_at);
            crc = crc32_update(crc, zero, 4u);
            crc = crc32_update(crc, &page[crc_at + 4u], n - crc_at - 4u);
        } else {
            crc = crc32_update(crc, page, n);
        }
        done += n;
    }
    return ~crc;
}

bool image_valid(struct hal *hal, uint8_t first_page, uint16_t model, struct image_info *out)
{
    struct image_info info;
    if (!image_parse_info(hal_flash_page(hal, first_page), &info) || info.model != model ||
        image_crc(hal, first_page, info.length) != info.crc)
        return false;
    if (out)
        *out = info;
    return true;
}

bool image_marked(struct hal *hal)
{
    const uint8_t *m = &hal_flash_page(hal, IMAGE_MARK_PAGE)[IMAGE_MARK_OFFSET];
    return m[0] == 0u && m[1] == 0u;
}

bool image_write_page(struct hal *hal, uint8_t page, const uint8_t *data, uint16_t n)
{
    if (!hal_flash_erase(hal, page))
        return false;
    for (uint16_t off = 0; off < n; off = (uint16_t)(off + 2u)) {
        uint16_t v = proto_get16(&data[off]);
        if (v != 0xFFFFu && !hal_flash_program(hal, page, off, v))
            return false;
    }
    return memcmp(hal_flash_page(hal, page), data, n) == 0;
}
