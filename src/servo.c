/* servo.c - power-up and the main-loop step of one servo. */
#include <string.h>

#include "boot.h"
#include "dispatch.h"
#include "hal.h"
#include "image.h"
#include "loader.h"
#include "motion.h"
#include "servo.h"

/* Register 2: the version in the running image's info block. (A host test that starts
 * the application on blank flash has no image: the build's version then.) */
static uint8_t running_version(struct hal *hal, const struct board *b)
{
    struct image_info info;
    if (image_parse_info(hal_flash_page(hal, HAL_PAGE_APP), &info) &&
        info.model == b->model_number)
        return info.version;
    return SERVO_FW_VERSION;
}

void servo_init(struct servo *s, const struct board *b, struct hal *hal)
{
    memset(s, 0, sizeof *s);
    s->hal = hal;
    s->board = b;
    s->fw_version = running_version(hal, b);
    regs_init(&s->regs, b);
    s->regs.mem[REG_FIRMWARE_VERSION] = s->fw_version;
    store_load(&s->store, hal, &s->regs, hal_clock_us(hal));
    frame_rx_init(&s->rx, link_baud(b, s->regs.mem[REG_BAUD_RATE]));
    link_latch(s);
    motion_init(s); /* motor off; the goal starts at the present position (rule 1) */
    hal_watchdog_start(s->hal); /* a hang resets the MCU, which comes up with the motor off */
}

void servo_rx_isr(struct servo *s, uint8_t byte)
{
    frame_rx_byte(&s->rx, byte, hal_clock_us(s->hal));
}

void servo_poll(struct servo *s)
{
    uint32_t now = hal_clock_us(s->hal);
    motion_poll(s, now);
    /* The control tick and the bus handling both run in this loop, so feeding here once
     * per pass proves both alive: a hang in either stops the feeding. */
    hal_watchdog_feed(s->hal);
    uint32_t irq = hal_irq_save(s->hal);
    bool rx_idle = frame_rx_idle(&s->rx, now);
    hal_irq_restore(s->hal, irq);
    bool link_idle = link_poll(s, now, rx_idle);
    /* Flash work (an erase stalls the CPU) only while nothing moves and the bus rests. */
    store_poll(&s->store, &s->regs, now, link_idle && rx_idle && !s->regs.mem[REG_MOVING]);
    if (!link_idle)
        return;
    if (s->restart) { /* a verified update: its ACK is out */
        store_flush(&s->store, &s->regs, now);
        hal_restart(s->hal);
        return;
    }
    (void)update_active(&s->update, now); /* a silent session times out */
    const struct frame *f = frame_rx_peek(&s->rx);
    const struct frame_block *blk = frame_rx_peek_block(&s->rx);
    if (f) {
        dispatch_frame(s, f);
        motion_report(s); /* what the command changed is what the next READ sees */
    } else if (blk)
        (void)loader_update_frame(s, blk->buf, blk->len, blk->status == FRAME_OK, blk->end_us);
    else
        return;
    frame_rx_release(&s->rx);
    store_sync(&s->store, &s->regs, now); /* what the frame changed in EEPROM, at once */
    if (s->link.state == LINK_IDLE)
        link_latch(s); /* no answer: a new ID or baud applies at once */
}

void servo_power_on(struct servo *s, const struct board *b, struct hal *hal)
{
    if (boot_install(hal, b->model_number))
        servo_init(s, b, hal);
    else
        loader_init(s, b, hal);
}

void servo_step(struct servo *s)
{
    if (s->in_loader)
        loader_poll(s);
    else
        servo_poll(s);
}
