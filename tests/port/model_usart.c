/* model_usart.c - USART1 (RM0008 §27.6), 8N1 with 16x oversampling, and the RS485 bus
 * behind its transceiver:
 *   - the bit rate is PCLK2 / BRR (USARTDIV = BRR / 16; BRR below 16 is not a rate);
 *   - receiving: the host's bytes arrive at the host's own bit rate; the receiver samples
 *     each bit in its middle at its own rate, so a rate too far off reads wrong bits or a
 *     framing error. At the stop bit RXNE is set, or ORE if RXNE still was (the byte is
 *     lost). Reading DR clears RXNE; SR then DR clears ORE, FE, NE, PE;
 *   - sending: DR to the shift register (TXE), 10 bits, then TC once nothing follows; SR
 *     then a DR write clears TC. Setting TE sends an idle frame first;
 *   - the transceiver: its receiver is off while the driver enable is high (DE and /RE
 *     tied), so the host's bytes then go unheard, unless the knob `echo` says it hears
 *     its own. Every byte sent is logged with whether DE was high all along; DE falling
 *     while a byte is on the wire, or a byte starting with DE low, is a violation. */
#include "model.h"
#include "model_parts.h"

#define SR_PE (1u << 0)
#define SR_FE (1u << 1)
#define SR_NE (1u << 2)
#define SR_ORE (1u << 3)
#define SR_RXNE (1u << 5)
#define SR_TC (1u << 6)
#define SR_TXE (1u << 7)
#define SR_ERRORS (SR_PE | SR_FE | SR_NE | SR_ORE)
#define CR1_RE (1u << 2)
#define CR1_TE (1u << 3)
#define CR1_RXNEIE (1u << 5)
#define CR1_TCIE (1u << 6)
#define CR1_TXEIE (1u << 7)
#define CR1_PCE (1u << 10)
#define CR1_M (1u << 12)
#define CR1_UE (1u << 13)
#define PIN_TX 0x09u /* PA9 */
#define PIN_RX 0x0Au /* PA10 */
#define ECHO_BIT 0x80000000u

static struct model_usart *const u = &model.usart;

static uint64_t bit_ticks(void)
{
    uint32_t brr = u->brr < 16u ? 16u : u->brr;
    return (uint64_t)brr * MODEL_HZ / model_pclk2_hz();
}

uint32_t model_usart_bps(void)
{
    if (!(u->cr1 & CR1_UE) || u->brr < 16u)
        return 0;
    return model_pclk2_hz() / u->brr;
}

bool usart_irq(void)
{
    return ((u->cr1 & CR1_RXNEIE) && (u->sr & (SR_RXNE | SR_ORE))) ||
           ((u->cr1 & CR1_TXEIE) && (u->sr & SR_TXE)) ||
           ((u->cr1 & CR1_TCIE) && (u->sr & SR_TC));
}

static bool de_high(void)
{
    return u->de_pin != 0xFFu && model_pin_state(u->de_pin) == MODEL_PIN_HIGH;
}

void usart_de_changed(bool high)
{
    if (!high && u->shifting && !u->idle_frame && u->shift_de_ok) {
        u->shift_de_ok = false;
        model_violation("driver enable released while byte 0x%02x was on the wire", u->shift);
    }
}

static void queue_rx(uint64_t start, uint64_t bit, uint8_t byte, bool echo)
{
    uint32_t next = (u->rx_tail + 1u) % MODEL_RX_QUEUE;
    if (next == u->rx_head) {
        model_violation("the model's receive queue is full");
        return;
    }
    u->rx[u->rx_tail].start = start;
    u->rx[u->rx_tail].bit = echo ? bit | ((uint64_t)ECHO_BIT << 32) : bit;
    u->rx[u->rx_tail].byte = byte;
    u->rx_tail = next;
}

void model_wire_send(const uint8_t *bytes, uint32_t n, uint32_t baud)
{
    uint64_t bit = (MODEL_HZ + baud / 2u) / baud;
    uint64_t t = u->wire_free > model.now ? u->wire_free : model.now;
    for (uint32_t i = 0; i < n; i++, t += 10u * bit)
        queue_rx(t, bit, bytes[i], false);
    u->wire_free = t;
}

uint32_t model_wire_take(uint32_t *from, uint8_t *out, uint32_t max)
{
    uint32_t n = 0;
    while (*from < u->tx_len && n < max)
        out[n++] = u->tx[(*from)++].byte;
    return n;
}

/* The receiver takes the byte whose stop bit it samples now. */
static void receive(uint64_t start, uint64_t sender_bit, uint8_t byte, bool echo)
{
    if (!(u->cr1 & CR1_UE) || !(u->cr1 & CR1_RE))
        return; /* nobody listens */
    if (!echo && u->de_pin != 0xFFu && model_pin_state(u->de_pin) != MODEL_PIN_LOW &&
        model_pin_state(u->de_pin) != MODEL_PIN_PULL_DOWN) {
        u->rx_unheard++; /* the transceiver's receiver is off (or /RE floats) */
        return;
    }
    enum model_pin rx = model_pin_state(PIN_RX);
    if (rx != MODEL_PIN_FLOATING && rx != MODEL_PIN_PULL_UP)
        model_violation("RX (PA10) is not an input while a byte arrives");
    uint64_t rb = bit_ticks();
    uint32_t bits = 0;
    for (uint32_t k = 0; k < 10u; k++) {
        uint64_t j = ((2u * k + 1u) * rb / 2u) / sender_bit; /* the sender's bit there */
        uint32_t level = j == 0 ? 0u : j <= 8u ? ((uint32_t)byte >> (j - 1u)) & 1u : 1u;
        bits |= level << k;
    }
    bool fe = !(bits & (1u << 9)) || (bits & 1u);
    if (u->sr & SR_RXNE) {
        u->sr |= SR_ORE; /* the new byte is lost; DR keeps the unread one */
        return;
    }
    u->rdr = (bits >> 1) & 0xFFu;
    u->sr |= SR_RXNE | (fe ? SR_FE : 0u);
    (void)start;
}

/* Load the transmit data register into the shift register (TXE again). */
static void load(uint64_t at)
{
    if (model_pin_state(PIN_TX) != MODEL_PIN_ALT)
        model_violation("TX (PA9) is not an alternate-function output when sending");
    if (u->cr2 & (3u << 12))
        model_violation("USART1 CR2 stop bits 0x%x (8N1: one stop bit)", (u->cr2 >> 12) & 3u);
    u->shift = u->tdr;
    u->tdr_full = false;
    u->sr |= SR_TXE;
    u->shifting = true;
    u->idle_frame = false;
    u->shift_start = at;
    u->shift_end = at + 10u * bit_ticks();
    u->shift_de_ok = de_high();
    if (!u->shift_de_ok)
        model_violation("byte 0x%02x started with the driver enable not high", u->shift);
}

void usart_sync(void)
{
    while (u->rx_head != u->rx_tail) {
        uint64_t sb = u->rx[u->rx_head].bit & 0xFFFFFFFFu;
        bool echo = (u->rx[u->rx_head].bit >> 32) != 0u;
        uint64_t start = u->rx[u->rx_head].start;
        if (start + 19u * bit_ticks() / 2u > model.now)
            break;
        receive(start, sb, u->rx[u->rx_head].byte, echo);
        u->rx_head = (u->rx_head + 1u) % MODEL_RX_QUEUE;
    }
    while (u->shifting && u->shift_end <= model.now) {
        u->shifting = false;
        if (!u->idle_frame) {
            if (u->tx_len < MODEL_TX_LOG) {
                struct model_tx *t = &u->tx[u->tx_len++];
                t->start = u->shift_start;
                t->end = u->shift_end;
                t->byte = u->shift;
                t->de_all_along = u->shift_de_ok;
            }
            if (u->echo)
                queue_rx(u->shift_start, bit_ticks(), u->shift, true);
        }
        if (u->tdr_full)
            load(u->shift_end);
        else
            u->sr |= SR_TC;
    }
}

uint64_t usart_next(void)
{
    uint64_t e = u->shifting ? u->shift_end : MODEL_NEVER;
    if (u->rx_head != u->rx_tail) {
        uint64_t r = u->rx[u->rx_head].start + 19u * bit_ticks() / 2u;
        if (r < e)
            e = r;
    }
    return e;
}

void usart_reset(uint8_t why)
{
    (void)why;
    u->sr = SR_TXE | SR_TC;
    u->rdr = 0;
    u->brr = 0;
    u->cr1 = u->cr2 = u->cr3 = 0;
    u->sr_read = false;
    u->tdr_full = u->shifting = u->idle_frame = false;
    u->rx_head = u->rx_tail = 0;
}

uint32_t usart_read(uint32_t off, uint32_t bytes)
{
    (void)bytes;
    switch (off) {
    case 0x00:
        u->sr_read = true;
        u->sr_seen = u->sr;
        return u->sr;
    case 0x04: {
        uint32_t v = u->rdr;
        u->sr &= ~SR_RXNE;
        if (u->sr_read)
            u->sr &= ~(u->sr_seen & SR_ERRORS);
        u->sr_read = false;
        return v;
    }
    case 0x08:
        return u->brr;
    case 0x0C:
        return u->cr1;
    case 0x10:
        return u->cr2;
    case 0x14:
        return u->cr3;
    default:
        model_violation("USART1 read at +0x%x", off);
        return 0;
    }
}

static void write_cr1(uint32_t v)
{
    uint32_t was = u->cr1;
    if (v & (CR1_M | CR1_PCE))
        model_violation("USART1 CR1 0x%x: 9 data bits or parity (8N1 expected)", v);
    u->cr1 = v & 0x3FFFu;
    if ((v & CR1_UE) && (v & CR1_TE) && !((was & CR1_UE) && (was & CR1_TE)) && !u->shifting) {
        u->shifting = true; /* RM0008: setting TE sends an idle frame first */
        u->idle_frame = true;
        u->shift_start = model.now;
        u->shift_end = model.now + 10u * bit_ticks();
    }
}

void usart_write(uint32_t off, uint32_t v, uint32_t bytes)
{
    (void)bytes;
    switch (off) {
    case 0x00: /* TC and RXNE clear on writing 0 */
        u->sr &= ~(~v & (SR_TC | SR_RXNE));
        break;
    case 0x04:
        if (!(u->cr1 & CR1_UE) || !(u->cr1 & CR1_TE))
            model_violation("USART1 DR written with the transmitter off");
        if (u->tdr_full) {
            model_violation("USART1 DR written while TXE was 0: byte 0x%02x lost", u->tdr);
            break;
        }
        if (u->sr_read)
            u->sr &= ~SR_TC; /* SR read, then DR written */
        u->sr_read = false;
        u->tdr = (uint8_t)v;
        u->tdr_full = true;
        u->sr &= ~SR_TXE;
        if (!u->shifting)
            load(model.now);
        break;
    case 0x08:
        if (u->shifting && !u->idle_frame)
            model_violation("USART1 BRR changed while byte 0x%02x was on the wire", u->shift);
        if (u->shifting && u->idle_frame) { /* the rest of the idle frame at the new rate */
            uint64_t old = bit_ticks(), left = (u->shift_end - model.now + old - 1u) / old;
            u->brr = v & 0xFFFFu;
            u->shift_end = model.now + left * bit_ticks();
        }
        u->brr = v & 0xFFFFu;
        break;
    case 0x0C:
        write_cr1(v);
        break;
    case 0x10:
        u->cr2 = v;
        break;
    case 0x14:
        if (v)
            model_violation("USART1 CR3 0x%x (the port uses none of it)", v);
        u->cr3 = v;
        break;
    default:
        model_violation("USART1 write of 0x%x at +0x%x", v, off);
        break;
    }
}
