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
    frame_rx_init(&s->rx, link_baud(b, s->regs.mem[REG_BAUD_RATE]));
    link_latch(s);
    motion_init(s); /* motor off; the goal starts at the present position (rule 1) */
}

void servo_rx_isr(struct servo *s, uint8_t byte)
{
    frame_rx_byte(&s->rx, byte, hal_clock_us(s->hal));
}

void servo_poll(struct servo *s)
{
    uint32_t now = hal_clock_us(s->hal);
    uint32_t irq = hal_irq_save(s->hal);
    bool rx_idle = frame_rx_idle(&s->rx, now);
    hal_irq_restore(s->hal, irq);
    if (!link_poll(s, now, rx_idle))
        return;
    const struct frame *f = frame_rx_peek(&s->rx);
    if (!f)
        return;
    dispatch_frame(s, f);
    frame_rx_release(&s->rx);
    if (s->link.state == LINK_IDLE)
        link_latch(s); /* no answer: a new ID or baud applies at once */
}
