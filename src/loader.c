/* loader.c - update mode (loader.h) and the answer to a §10 frame, which the
 * application's dispatcher shares. */
#include <string.h>

#include "hal.h"
#include "loader.h"
#include "proto.h"

uint8_t loader_update_frame(struct servo *s, const uint8_t *buf, uint16_t len, bool chk_ok,
                            uint32_t end_us)
{
    struct link *l = &s->link;
    if (buf[0] != l->id)
        return UPDATE_GO_ON; /* §10 frames go to one ID; a broadcast is not for us */
    uint8_t ans[2], n;
    uint8_t out = update_frame(&s->update, s->hal, s->board->model_number, buf, len, chk_ok,
                               end_us, ans, &n);
    /* Always answered (whatever register 16 says), ERR 0, after the return delay. */
    link_answer(s, l->id, 0, ans, n, end_us + (uint32_t)l->delay * 500u);
    if (out == UPDATE_RESTART)
        s->restart = 1;
    return out;
}

void loader_init(struct servo *s, const struct board *b, struct hal *hal)
{
    memset(s, 0, sizeof *s);
    s->hal = hal;
    s->board = b;
    s->in_loader = 1;
    regs_init(&s->regs, b);
    store_load(&s->store, hal, &s->regs, hal_clock_us(hal));
    frame_rx_init(&s->rx, link_baud(b, s->regs.mem[REG_BAUD_RATE]));
    link_latch(s);
}

void loader_poll(struct servo *s)
{
    uint32_t now = hal_clock_us(s->hal);
    uint32_t irq = hal_irq_save(s->hal);
    bool rx_idle = frame_rx_idle(&s->rx, now);
    hal_irq_restore(s->hal, irq);
    if (!link_poll(s, now, rx_idle))
        return;
    if (s->restart) {
        hal_restart(s->hal); /* the ACK is out: the bootloader installs the image */
        return;
    }
    (void)update_active(&s->update, now);
    const struct frame *f = frame_rx_peek(&s->rx);
    const struct frame_block *blk = frame_rx_peek_block(&s->rx);
    if (f && update_is_frame(f->buf, f->len))
        (void)loader_update_frame(s, f->buf, f->len, f->status == FRAME_OK, f->end_us);
    else if (blk)
        (void)loader_update_frame(s, blk->buf, blk->len, blk->status == FRAME_OK, blk->end_us);
    if (f || blk)
        frame_rx_release(&s->rx);
}
