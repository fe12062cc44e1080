/* image_build.c - synthetic application images (image_build.h). */
#include "crc.h"
#include "image.h"
#include "image_build.h"

static void put32(uint8_t *p, uint32_t v)
{
    for (uint8_t i = 0; i < 4u; i++)
        p[i] = (uint8_t)(v >> (8u * i));
}

void hal_host_image_stamp(uint8_t *img, uint32_t len)
{
    uint8_t *info = &img[IMAGE_INFO_OFFSET];
    put32(&info[IMAGE_OFF_CRC], 0);
    put32(&info[IMAGE_OFF_CRC], ~crc32_update(CRC32_INIT, img, len));
}

void hal_host_image_build(uint8_t *img, uint32_t len, uint16_t model, uint8_t version,
                          uint32_t seed)
{
    uint32_t x = seed * 2654435761u + 0x9E3779B9u;
    for (uint32_t i = 0; i < len; i++) {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        img[i] = (uint8_t)x;
    }
    uint8_t *info = &img[IMAGE_INFO_OFFSET];
    put32(&info[IMAGE_OFF_MAGIC], IMAGE_MAGIC);
    put32(&info[IMAGE_OFF_LENGTH], len);
    info[IMAGE_OFF_MODEL] = (uint8_t)model;
    info[IMAGE_OFF_MODEL + 1u] = (uint8_t)(model >> 8);
    info[IMAGE_OFF_VERSION] = version;
    info[IMAGE_OFF_RESERVED] = 0;
    hal_host_image_stamp(img, len);
}
