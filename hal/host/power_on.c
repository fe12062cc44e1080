/* power_on.c - the host's model of the MCU's power-up (hal_host.h): the bootloader's
 * decision, then the application, update mode, or an image that hangs at start. The
 * hang is the host's alone: the firmware core has no notion of it (struct hal keeps it). */
#include <string.h>

#include "boot.h"
#include "hal_host.h"
#include "image.h"
#include "link.h"
#include "loader.h"
#include "servo.h"

void servo_power_on(struct servo *s, const struct board *b, struct hal *hal)
{
    bool start = boot_start(hal, b->model_number);
    hal_watchdog_start(hal); /* as the bootloader: before the jump, or for update mode */
    hal->image_hung = false;
    if (!start) {
        loader_init(s, b, hal);
        return;
    }
    if (hal_flash_page(hal, HAL_PAGE_APP)[IMAGE_INFO_OFFSET + IMAGE_OFF_RESERVED] ==
        IMAGE_HOST_HANG) {
        memset(s, 0, sizeof *s);
        s->hal = hal;
        s->board = b;
        hal->image_hung = true;
        hal->hung_since_us = hal_clock_us(hal);
        frame_rx_init(&s->rx, link_baud(b, 0)); /* a harness may still hand it bytes */
        return;
    }
    servo_init(s, b, hal);
}

void servo_step(struct servo *s)
{
    if (!s->hal->image_hung)
        servo_poll(s);
    else if (hal_clock_us(s->hal) - s->hal->hung_since_us >= SERVO_WATCHDOG_US)
        hal_restart(s->hal); /* the watchdog: never fed since the start */
}
