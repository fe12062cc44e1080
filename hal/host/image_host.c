/* image_host.c - synthetic application images for the host model (hal_host.h). */
#include "hal_host.h"
#include "image.h"

void hal_host_image_hang(uint8_t *img, uint32_t len)
{
    img[IMAGE_INFO_OFFSET + IMAGE_OFF_RESERVED] = IMAGE_HOST_HANG;
    hal_host_image_stamp(img, len);
}

void hal_host_program_factory(struct hal *h, const struct board *b)
{
    static uint8_t img[HAL_HOST_FACTORY_BYTES];
    hal_host_image_build(img, sizeof img, b->model_number, SERVO_FW_VERSION, 1);
    hal_host_program_app(h, img, sizeof img);
}
