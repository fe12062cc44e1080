/* link.c - settings in force and answer scheduling (PROTOCOL.md §1, §3.2). */
#include "hal.h"
#include "link.h"
#include "servo.h"

/* The rates of the baud codes in hundreds of baud: every one is a whole number of them
 * under 65536, so half-words (a table half the size) hold them exactly. */
#define BAUD_UNIT 100u
static const uint16_t baud_codes[] = {
    0, 24, 96, 384, 1152, 2560, 4608, 8960, 9216, 12800, 17920,
};
/* Not inlined: one copy for its callers, smaller under -flto (measured). */
__attribute__((noinline)) uint32_t link_baud(const struct board *b, uint8_t code)
{
    if (code == 0)
        return b->default_baud;
    return code < sizeof baud_codes / sizeof baud_codes[0] ? baud_codes[code] * BAUD_UNIT : 0u;
}

bool link_baud_reachable(const struct servo *s, uint8_t addr, const uint8_t *data, uint8_t n)
{
    if (addr > REG_BAUD_RATE || REG_BAUD_RATE - addr >= n)
        return true;
    uint32_t want = link_baud(servo_board(s), data[REG_BAUD_RATE - addr]);
    uint32_t got = hal_uart_baud_achieved(s->hal, want);
    return (got > want ? got - want : want - got) <= want / 50u;
}

uint32_t link_bytes_us(uint32_t baud, uint32_t n)
{
    /* 32-bit only (no 64-bit division in the image); exact for n < 2000 bytes. */
    uint32_t bits_us = 10u * 1000000u;
    return n * (bits_us / baud) + (n * (bits_us % baud) + baud - 1u) / baud;
}

uint32_t link_ping_slot_us(const struct link *l)
{
    return (uint32_t)l->id * link_bytes_us(l->baud, 9u);
}

void link_settings_written(struct link *l)
{
    l->relatch = 1;
}

void link_latch(struct servo *s)
{
    struct link *l = &s->link;
    l->relatch = 0;
#ifndef SERVO_BOOTLOADER /* update mode leaves the terminator as reset left it: off */
    hal_rs485_termination(s->hal, s->regs.mem[REG_RS485_TERMINATION] != 0u);
#endif
    l->id = s->regs.mem[REG_ID];
    l->level = s->regs.mem[REG_STATUS_RETURN_LEVEL];
    l->report = s->regs.mem[REG_UNLOAD_CONDITIONS] & (UNLOAD_REPORT_INSTRUCTION |
                                                      UNLOAD_REPORT_CHECKSUM);
    l->delay = s->regs.mem[REG_RETURN_DELAY];
    uint32_t baud = link_baud(servo_board(s), s->regs.mem[REG_BAUD_RATE]);
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
        if (l->relatch)
            link_latch(s); /* the answer is out: written settings take effect (§1) */
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
