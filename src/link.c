/* link.c - settings in force and answer scheduling (PROTOCOL.md §1, §3.2). */
#include "hal.h"
#include "link.h"
#include "servo.h"

static const uint32_t baud_codes[] = {
    0, 2400, 9600, 38400, 115200, 256000, 460800, 896000, 921600, 1280000, 1792000,
};

uint32_t link_baud(const struct board *b, uint8_t code)
{
    if (code == 0)
        return b->default_baud;
    return code < sizeof baud_codes / sizeof baud_codes[0] ? baud_codes[code] : 0;
}

uint32_t link_bytes_us(uint32_t baud, uint32_t n)
{
    /* 32-bit only (no 64-bit division in the image); exact for n < 2000 bytes. */
    uint32_t bits_us = 10u * 1000000u;
    return n * (bits_us / baud) + (n * (bits_us % baud) + baud - 1u) / baud;
}

void link_latch(struct servo *s)
{
    struct link *l = &s->link;
    l->id = s->regs.mem[REG_ID];
    l->level = s->regs.mem[REG_STATUS_RETURN_LEVEL];
    l->report = s->regs.mem[REG_UNLOAD_CONDITIONS] & (UNLOAD_REPORT_INSTRUCTION |
                                                      UNLOAD_REPORT_CHECKSUM);
    l->delay = s->regs.mem[REG_RETURN_DELAY];
    uint32_t baud = link_baud(s->board, s->regs.mem[REG_BAUD_RATE]);
    if (baud != l->baud) {
        l->baud = baud;
        hal_uart_set_baud(s->hal, baud);
        uint32_t irq = hal_irq_save(s->hal);
        frame_rx_set_baud(&s->rx, baud);
        hal_irq_restore(s->hal, irq);
    }
}

void link_answer(struct servo *s, uint8_t id, uint8_t err, const uint8_t *data, uint8_t n,
                 uint32_t at_us)
{
    struct link *l = &s->link;
    l->tx_len = proto_build_packet(l->tx, id, err, data, n);
    l->due_us = at_us;
    l->state = LINK_WAITING;
}

bool link_poll(struct servo *s, uint32_t now_us, bool rx_idle)
{
    struct link *l = &s->link;
    switch (l->state) {
    case LINK_SENDING:
        if (hal_uart_tx_busy(s->hal))
            return false;
        l->state = LINK_IDLE;
        link_latch(s); /* the answer is out: new settings may take effect */
        return true;
    case LINK_WAITING:
        /* Never talk over a frame that is still arriving (half duplex). */
        if ((int32_t)(now_us - l->due_us) < 0 || !rx_idle)
            return false;
        hal_uart_send(s->hal, l->tx, l->tx_len);
        l->state = LINK_SENDING;
        return false;
    default:
        return true;
    }
}

uint32_t link_reply_at(const struct link *l, uint32_t end_us)
{
    return end_us + (uint32_t)l->delay * LINK_DELAY_UNIT_US;
}
