/* image_build.h - synthetic application images (include/image.h layout) stamped with the
 * core's CRC-32, as tools/fwstamp.py stamps a build: for the host model (hal_host.h)
 * and for the port's register-model tests (tests/port), which cannot include the host
 * HAL. No HAL here. (image_build.c) */
#ifndef IMAGE_BUILD_H
#define IMAGE_BUILD_H

#include <stdint.h>

/* A synthetic application image of len bytes for a board of this model, with the given
 * version; seed varies its content. len >= IMAGE_MIN_BYTES. */
void hal_host_image_build(uint8_t *img, uint32_t len, uint16_t model, uint8_t version,
                          uint32_t seed);

/* Stamp img's CRC again after a change to its bytes (info block included). */
void hal_host_image_stamp(uint8_t *img, uint32_t len);

#endif
