/* servo.c - power-up and the main-loop step of one servo. */
#include <string.h>

#include "dispatch.h"
#include "hal.h"
#include "motion.h"
#include "servo.h"

void servo_init(struct servo *s, const struct board *b, struct hal *hal)
{
    memset(s, 0, sizeof *s);
    s->hal = hal;
    s->board = b;
    regs_init(&s->regs, b);
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
    const struct frame *f = frame_rx_peek(&s->rx);
    if (!f)
        return;
    dispatch_frame(s, f);
    frame_rx_release(&s->rx);
    store_sync(&s->store, &s->regs, now); /* what the frame changed in EEPROM, at once */
    if (s->link.state == LINK_IDLE)
        link_latch(s); /* no answer: a new ID or baud applies at once */
}
