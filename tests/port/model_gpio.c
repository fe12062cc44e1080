/* model_gpio.c - GPIO ports A to C (RM0008 §9.2): CRL/CRH (a 4-bit MODE/CNF field per
 * pin; reset: floating input), ODR (also the pull direction of a pulled input), IDR,
 * BSRR (set wins over reset) and BRR; an open-drain output's 1 lets the pin go. What
 * the board sees on each pin, and the edges of one pin the test watches (the RS485
 * driver enable). */
#include "model.h"
#include "model_parts.h"

static struct model_gpio *const g = &model.gpio;

static uint32_t cfg(uint32_t port, uint32_t n)
{
    uint32_t reg = n < 8u ? g->crl[port] : g->crh[port];
    return (reg >> ((n & 7u) * 4u)) & 0xFu;
}

enum model_pin model_pin_state(uint8_t pin)
{
    uint32_t port = pin >> 4, n = pin & 15u;
    if (port > 2u)
        return MODEL_PIN_FLOATING;
    uint32_t c = cfg(port, n), mode = c & 3u, cnf = c >> 2;
    bool high = (g->odr[port] >> n) & 1u;
    if (mode != 0u && (cnf & 2u)) /* an output: CNF bit 1 selects the alternate function */
        return MODEL_PIN_ALT;
    if (mode != 0u) /* CNF bit 0: open drain, whose 1 lets the pin go */
        return !high ? MODEL_PIN_LOW : (cnf & 1u) ? MODEL_PIN_FLOATING : MODEL_PIN_HIGH;
    if (cnf == 2u)
        return high ? MODEL_PIN_PULL_UP : MODEL_PIN_PULL_DOWN;
    return MODEL_PIN_FLOATING; /* analog, floating input (or the reserved code) */
}

void model_pin_drive(uint8_t pin, int level)
{
    uint32_t port = pin >> 4, bit = 1u << (pin & 15u);
    if (level < 0) {
        g->ext_driven[port] &= ~bit;
        return;
    }
    g->ext_driven[port] |= bit;
    g->ext_high[port] = level ? g->ext_high[port] | bit : g->ext_high[port] & ~bit;
}

/* Log the watched pin's state when it changes; tell the USART about its enable. */
static void watch(uint8_t before[2])
{
    uint8_t pins[2] = {g->watch, model.usart.de_pin};
    for (int i = 0; i < 2; i++) {
        if (pins[i] == 0xFFu)
            continue;
        uint8_t now = (uint8_t)model_pin_state(pins[i]);
        if (now == before[i])
            continue;
        if (i == 1)
            usart_de_changed(now == MODEL_PIN_HIGH);
        else if (g->edges < sizeof g->edge / sizeof g->edge[0]) {
            g->edge[g->edges].at = model.now;
            g->edge[g->edges].state = now;
            g->edges++;
        }
    }
}

void gpio_reset(uint8_t why)
{
    (void)why;
    uint8_t before[2] = {0xFF, 0xFF};
    if (g->watch != 0xFFu)
        before[0] = (uint8_t)model_pin_state(g->watch);
    if (model.usart.de_pin != 0xFFu)
        before[1] = (uint8_t)model_pin_state(model.usart.de_pin);
    for (int p = 0; p < 3; p++) {
        g->crl[p] = 0x44444444u;
        g->crh[p] = 0x44444444u;
        g->odr[p] = 0;
    }
    watch(before);
}

uint32_t gpio_read(uint32_t off, uint32_t bytes)
{
    (void)bytes;
    uint32_t port = off >> 10, reg = off & 0x3FFu;
    switch (reg) {
    case 0x00:
        return g->crl[port];
    case 0x04:
        return g->crh[port];
    case 0x08: { /* IDR: outputs read back their level, inputs the board's */
        uint32_t v = 0;
        for (uint32_t n = 0; n < 16u; n++) {
            uint32_t c = cfg(port, n), bit = 1u << n;
            bool high;
            if ((c & 3u) && ((c & 8u) || !(c & 4u) || !(g->odr[port] & bit)))
                high = (c & 8u) ? true : (g->odr[port] & bit) != 0u; /* AF: idle high */
            else if (g->ext_driven[port] & bit) /* an input, or an open drain let go */
                high = (g->ext_high[port] & bit) != 0u;
            else
                high = (c >> 2) == 2u && (g->odr[port] & bit); /* the pull, or nothing */
            v |= high ? bit : 0u;
        }
        return v;
    }
    case 0x0C:
        return g->odr[port];
    default:
        model_violation("GPIO read at +0x%x", reg);
        return 0;
    }
}

void gpio_write(uint32_t off, uint32_t v, uint32_t bytes)
{
    (void)bytes;
    uint32_t port = off >> 10, reg = off & 0x3FFu;
    uint8_t before[2] = {0xFF, 0xFF};
    if (g->watch != 0xFFu)
        before[0] = (uint8_t)model_pin_state(g->watch);
    if (model.usart.de_pin != 0xFFu)
        before[1] = (uint8_t)model_pin_state(model.usart.de_pin);
    switch (reg) {
    case 0x00:
        g->crl[port] = v;
        break;
    case 0x04:
        g->crh[port] = v;
        break;
    case 0x0C:
        g->odr[port] = v & 0xFFFFu;
        break;
    case 0x10: /* BSRR: set bits 0-15, reset bits 16-31; set wins */
        g->odr[port] = ((g->odr[port] & ~(v >> 16)) | v) & 0xFFFFu;
        break;
    case 0x14:
        g->odr[port] &= ~(v & 0xFFFFu);
        break;
    default:
        model_violation("GPIO write of 0x%x at +0x%x", v, reg);
        break;
    }
    watch(before);
}
