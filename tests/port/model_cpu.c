/* model_cpu.c - the Cortex-M3's system control space as the port uses it (ARMv7-M ARM,
 * Cortex-M3 TRM): SysTick (counts HCLK down from RVR; the 1 -> 0 step pends its
 * exception), the NVIC's enable and priority registers for USART1, SCB's ICSR
 * (PENDSTSET), SHPR3 (SysTick's priority), VTOR and AIRCR (SYSRESETREQ). And exception
 * entry: the pending exception with the best priority runs when it beats both the
 * handler running and BASEPRI (4 priority bits, lower is more urgent). */
#include <stddef.h>

#include "model.h"
#include "model_parts.h"

#define IRQ_USART1 37u
#define CSR_ENABLE (1u << 0)
#define CSR_TICKINT (1u << 1)
#define CSR_CLKSOURCE (1u << 2)
#define ICSR_PENDSTSET (1u << 26)
#define AIRCR_KEY 0x05FA0000u
#define AIRCR_SYSRESETREQ (1u << 2)
#define THREAD 0x100u

/* The port's handlers (uart.c, clock.c); weak so a test without one still links. */
void usart1_handler(void) __attribute__((weak));
void systick_handler(void) __attribute__((weak));

static struct model_cpu *const c = &model.cpu;

static uint64_t st_cycle(void)
{
    uint64_t t = model_cycle_ticks();
    return (c->st_csr & CSR_CLKSOURCE) ? t : 8u * t;
}

/* Cycles counted since the counter was written 0, and the value it shows. */
static uint64_t st_cycles(void)
{
    return (c->st_csr & CSR_ENABLE) ? (model.now - c->st_base) / st_cycle() : 0u;
}

static uint32_t st_value(void)
{
    uint64_t k = st_cycles();
    if (k == 0u)
        return 0u;
    return c->st_rvr - (uint32_t)((k - 1u) % ((uint64_t)c->st_rvr + 1u));
}

void cpu_sync(void)
{
    if (!(c->st_csr & CSR_ENABLE) || c->st_rvr == 0u)
        return;
    uint64_t wraps = st_cycles() / ((uint64_t)c->st_rvr + 1u);
    if (wraps > c->st_wraps) {
        c->st_wraps = wraps;
        if (c->st_csr & CSR_TICKINT)
            c->st_pending = true;
    }
}

uint64_t cpu_next(void)
{
    if (!(c->st_csr & CSR_ENABLE) || c->st_rvr == 0u)
        return MODEL_NEVER;
    return c->st_base + (c->st_wraps + 1u) * ((uint64_t)c->st_rvr + 1u) * st_cycle();
}

static void run_handler(void (*fn)(void), uint8_t prio, const char *name)
{
    if (fn == NULL) {
        model_violation("%s taken, but the test links no handler for it", name);
        return;
    }
    uint8_t was = c->handler;
    c->handler = prio ? prio : 1u; /* priority 0 still runs as a handler */
    fn();
    c->handler = was;
}

static uint32_t masked_prio(uint8_t ip)
{
    return ip & 0xF0u;
}

void cpu_deliver(void)
{
    for (;;) {
        uint32_t exec = c->handler ? c->handler : THREAD;
        if (model_basepri && model_basepri < exec)
            exec = model_basepri & 0xF0u;
        uint32_t st = masked_prio(c->shp[11]), us = masked_prio(c->ip[IRQ_USART1]);
        bool us_on = (c->iser[1] >> (IRQ_USART1 - 32u)) & 1u;
        if (model.now != c->storm_at) { /* a new instant: count entries afresh */
            c->storm_at = model.now;
            c->storm = 0;
        }
        if (c->st_pending && st < exec && (!(us_on && usart_irq()) || st <= us)) {
            c->st_pending = false; /* PENDSTSET clears on entry */
            run_handler(systick_handler, (uint8_t)st, "SysTick");
        } else if (us_on && usart_irq() && us < exec) {
            run_handler(usart1_handler, (uint8_t)us, "USART1");
        } else {
            return;
        }
        if (model.now == c->storm_at && ++c->storm > 1000u) {
            model_violation("an interrupt is taken again and again without being cleared");
            return;
        }
    }
}

void cpu_reset(uint8_t why)
{
    (void)why;
    c->handler = 0;
    c->basepri = 0;
    c->st_csr = 0;
    c->st_rvr = 0;
    c->st_base = model.now;
    c->st_wraps = 0;
    c->st_pending = false;
    c->iser[0] = c->iser[1] = 0;
    for (unsigned i = 0; i < sizeof c->ip; i++)
        c->ip[i] = 0;
    for (unsigned i = 0; i < sizeof c->shp; i++)
        c->shp[i] = 0;
    c->vtor = 0;
    c->storm = 0;
}

uint32_t cpu_read(uint32_t off, uint32_t bytes)
{
    (void)bytes;
    switch (off) {
    case 0x010:
        return c->st_csr; /* COUNTFLAG not modelled: the port does not read it */
    case 0x014:
        return c->st_rvr;
    case 0x018:
        return st_value();
    case 0xD04:
        return c->st_pending ? ICSR_PENDSTSET : 0u;
    case 0xD08:
        return c->vtor;
    default:
        model_violation("system control space read at 0xE000E%03X", off);
        return 0;
    }
}

void cpu_write(uint32_t off, uint32_t v, uint32_t bytes)
{
    if (off >= 0x400u && off < 0x400u + sizeof c->ip) { /* NVIC IPR, byte-wide */
        if (bytes != 1u)
            model_violation("NVIC priority written %u bytes wide", bytes);
        c->ip[off - 0x400u] = (uint8_t)v;
        return;
    }
    if (off >= 0xD18u && off < 0xD18u + sizeof c->shp) { /* SHPR1-3, byte-wide */
        c->shp[off - 0xD18u] = (uint8_t)v;
        return;
    }
    switch (off) {
    case 0x010:
        if ((v & CSR_ENABLE) && !(c->st_csr & CSR_ENABLE)) {
            c->st_base = model.now;
            c->st_wraps = 0;
        }
        c->st_csr = v & 7u;
        break;
    case 0x014:
        c->st_rvr = v & 0xFFFFFFu;
        break;
    case 0x018: /* any write clears the counter */
        c->st_base = model.now;
        c->st_wraps = 0;
        break;
    case 0x100:
    case 0x104:
        c->iser[(off - 0x100u) / 4u] |= v;
        break;
    case 0x180:
    case 0x184:
        c->iser[(off - 0x180u) / 4u] &= ~v;
        break;
    case 0xD08:
        c->vtor = v;
        break;
    case 0xD0C:
        if ((v & 0xFFFF0000u) != AIRCR_KEY) {
            model_violation("AIRCR written without its key");
            break;
        }
        if (v & AIRCR_SYSRESETREQ) {
            model_reset(MODEL_RESET_SOFT);
            model_stop(MODEL_EXIT_RESET);
        }
        break;
    default:
        model_violation("system control space write of 0x%x at 0xE000E%03X", v, off);
        break;
    }
}
