/* model_rcc.c - reset and clock control (RM0008 §7.3): HSI, the crystal (knob), the PLL
 * (knob), the system clock switch and the bus prescalers; the reset flags; peripheral
 * clock enables. Checks what RM0008 requires of a switch to the PLL: the PLL set up
 * while off, flash wait states for the new clock, APB1 within 36 MHz. */
#include "model.h"
#include "model_parts.h"

#define CR_HSION (1u << 0)
#define CR_HSIRDY (1u << 1)
#define CR_HSEON (1u << 16)
#define CR_HSERDY (1u << 17)
#define CR_CSSON (1u << 19)
#define CR_PLLON (1u << 24)
#define CR_PLLRDY (1u << 25)
#define CFGR_PLL_BITS (0x3Fu << 16) /* PLLSRC, PLLXTPRE, PLLMUL */
#define CSR_FLAGS 0xFC000000u      /* PINRSTF .. LPWRRSTF */
#define CSR_RMVF (1u << 24)
#define CSR_PINRSTF (1u << 26)
#define CSR_PORRSTF (1u << 27)
#define CSR_SFTRSTF (1u << 28)
#define CSR_IWDGRSTF (1u << 29)

static struct model_rcc *const r = &model.rcc;

static bool hse_ready(void)
{
    return (r->cr & CR_HSEON) && r->crystal && model.now >= r->hse_ready_at;
}

static bool pll_ready(void)
{
    return (r->cr & CR_PLLON) && r->pll_locks && model.now >= r->pll_ready_at;
}

/* SWS: the clock that runs the system (0 HSI, 1 HSE, 2 PLL). */
static uint32_t sws(void)
{
    return (r->cfgr >> 2) & 3u;
}

static uint32_t pll_hz(void)
{
    uint32_t mul = ((r->cfgr >> 18) & 0xFu) + 2u;
    if (mul > 16u)
        mul = 16u;
    uint32_t in = (r->cfgr & (1u << 16)) ? 8000000u >> ((r->cfgr >> 17) & 1u) : 4000000u;
    return in * mul;
}

uint32_t model_sysclk_hz(void)
{
    switch (sws()) {
    case 1:
        return 8000000u;
    case 2:
        return pll_hz();
    default:
        return 8000000u;
    }
}

static uint32_t apb_div(uint32_t bits)
{
    return (bits & 4u) ? 2u << (bits & 3u) : 1u;
}

uint32_t model_pclk1_hz(void)
{
    return model_sysclk_hz() / apb_div((r->cfgr >> 8) & 7u);
}

uint32_t model_pclk2_hz(void)
{
    return model_sysclk_hz() / apb_div((r->cfgr >> 11) & 7u);
}

uint32_t model_tim_apb1_hz(void)
{
    uint32_t div = apb_div((r->cfgr >> 8) & 7u);
    return div == 1u ? model_pclk1_hz() : 2u * model_pclk1_hz();
}

uint32_t model_adc_hz(void)
{
    return model_pclk2_hz() / (2u * (((r->cfgr >> 14) & 3u) + 1u));
}

bool rcc_clock_on(uint32_t reg, uint32_t bit)
{
    uint32_t v = reg == 0 ? r->ahbenr : reg == 1 ? r->apb2enr : r->apb1enr;
    return (v >> bit) & 1u;
}

void rcc_reset(uint8_t why)
{
    r->cr = CR_HSION | CR_HSIRDY | (16u << 3);
    r->cfgr = 0;
    r->ahbenr = 0x14u; /* SRAM and FLITF clocked */
    r->apb2enr = 0;
    r->apb1enr = 0;
    if (why == MODEL_RESET_POWER)
        r->csr = CSR_PORRSTF | CSR_PINRSTF;
    else /* an internal reset drives NRST low too */
        r->csr |= CSR_PINRSTF | (why == MODEL_RESET_IWDG ? CSR_IWDGRSTF : CSR_SFTRSTF);
    r->hse_ready_at = MODEL_NEVER;
    r->pll_ready_at = MODEL_NEVER;
}

uint32_t rcc_read(uint32_t off, uint32_t bytes)
{
    (void)bytes;
    switch (off) {
    case 0x00:
        return (r->cr & ~(CR_HSERDY | CR_PLLRDY)) | (hse_ready() ? CR_HSERDY : 0u) |
               (pll_ready() ? CR_PLLRDY : 0u);
    case 0x04:
        return r->cfgr;
    case 0x14:
        return r->ahbenr;
    case 0x18:
        return r->apb2enr;
    case 0x1C:
        return r->apb1enr;
    case 0x24:
        return r->csr;
    default:
        model_violation("RCC read at +0x%x, which the port does not use", off);
        return 0;
    }
}

static void write_cr(uint32_t v)
{
    uint32_t was = r->cr;
    if ((v & CR_HSEON) && !(was & CR_HSEON))
        r->hse_ready_at = model.now + MODEL_MS(2);
    if (!(v & CR_HSEON) && (was & CR_HSEON) &&
        (sws() == 1u || (sws() == 2u && (r->cfgr & (1u << 16)))))
        model_violation("HSE switched off while it clocks the system");
    if ((v & CR_PLLON) && !(was & CR_PLLON)) {
        bool src = (r->cfgr & (1u << 16)) ? hse_ready() : true;
        r->pll_ready_at = src ? model.now + MODEL_US(200) : MODEL_NEVER;
    }
    if (!(v & CR_PLLON) && (was & CR_PLLON) && sws() == 2u)
        model_violation("PLL switched off while it clocks the system");
    if (!(v & CR_HSION))
        model_violation("HSION cleared (it clocks the system at reset)");
    if ((v & CR_CSSON) && !hse_ready())
        model_violation("clock security system on without a ready HSE");
    r->cr = (v & ~(CR_HSIRDY | CR_HSERDY | CR_PLLRDY)) | CR_HSIRDY;
}

static void write_cfgr(uint32_t v)
{
    if ((r->cr & CR_PLLON) && ((v ^ r->cfgr) & CFGR_PLL_BITS))
        model_violation("PLL source or multiplier changed while the PLL is on");
    uint32_t sw = v & 3u, now_sws = sws();
    bool ready = sw == 0u || (sw == 1u && hse_ready()) || (sw == 2u && pll_ready());
    r->cfgr = (v & ~(3u << 2)) | ((ready ? sw : now_sws) << 2);
    if (sws() != now_sws || sw == 2u) {
        uint32_t hz = model_sysclk_hz();
        uint32_t ws = hz > 48000000u ? 2u : hz > 24000000u ? 1u : 0u;
        if (fpec_wait_states() < ws)
            model_violation("system clock %u Hz with %u flash wait states (RM0008 §3.3.3)",
                            hz, fpec_wait_states());
        if (model_pclk1_hz() > 36000000u)
            model_violation("APB1 at %u Hz (36 MHz at most)", model_pclk1_hz());
        if (hz > 72000000u)
            model_violation("system clock %u Hz (72 MHz at most)", hz);
    }
}

void rcc_write(uint32_t off, uint32_t v, uint32_t bytes)
{
    (void)bytes;
    switch (off) {
    case 0x00:
        write_cr(v);
        break;
    case 0x04:
        write_cfgr(v);
        break;
    case 0x14:
        r->ahbenr = v;
        break;
    case 0x18:
        r->apb2enr = v;
        break;
    case 0x1C:
        r->apb1enr = v;
        break;
    case 0x24:
        if (v & CSR_RMVF)
            r->csr &= ~CSR_FLAGS;
        break;
    default:
        model_violation("RCC write of 0x%x at +0x%x, which the port does not use", v, off);
        break;
    }
}

uint64_t rcc_next(void)
{
    return MODEL_NEVER; /* the ready bits are worked out when read */
}

void rcc_sync(void)
{
}
