/* model_adc.c - ADC1 (RM0008 §11) and DMA1 channel 1 (§13.4), which serves it:
 *   - power-up (ADON), reset calibration and calibration (RSTCAL, CAL: cleared by the
 *     ADC when done);
 *   - a regular scan of SQR's channels (SCAN; L + 1 of them), each sampled for its
 *     SMPR time and converted in 12.5 more ADC cycles: the result is the board's input
 *     (knob `analog`) at the end of the sampling, the hold instant;
 *   - started by SWSTART (EXTTRIG with EXTSEL = SWSTART), again and again (CONT), or by
 *     each rising edge of TIM3's TRGO (EXTSEL 100: RM0008 table 69) 2 ADC cycles later
 *     (the datasheet's regular trigger latency, tlatr); a trigger that comes
 *     while a scan is still converting is ignored (an assumption: RM0008 does not say,
 *     so the port keeps its scans shorter than a PWM period);
 *   - DMA1 channel 1 copies each result, 16 bits, from DR to memory, circularly.
 * The ADC clock above 14 MHz is a violation. */
#include "model.h"
#include "model_parts.h"

enum { SR, CR1, CR2, SMPR1, SMPR2, SQR1 = 11, SQR2, SQR3, DR = 19 };
#define CR1_SCAN (1u << 8)
#define CR2_ADON (1u << 0)
#define CR2_CONT (1u << 1)
#define CR2_CAL (1u << 2)
#define CR2_RSTCAL (1u << 3)
#define CR2_DMA (1u << 8)
#define CR2_EXTTRIG (1u << 20)
#define CR2_SWSTART (1u << 22)
#define EXTSEL(cr2) (((cr2) >> 17) & 7u)
#define EXTSEL_TIM3_TRGO 4u
#define EXTSEL_SWSTART 7u
#define DMA_EN (1u << 0)
#define DMA_CIRC (1u << 5)
#define DMA_MINC (1u << 7)
#define ADC_DR_ADDR 0x4001244Cu

static struct model_adc *const a = &model.adc;

/* Sampling times, in half ADC cycles, of SMP codes 0..7 (1.5 .. 239.5 cycles). */
static const uint32_t smp_half[8] = {3, 15, 27, 57, 83, 111, 143, 479};

static uint64_t half_cycle(void)
{
    return MODEL_HZ / (2u * model_adc_hz());
}

static uint8_t channel_at(uint32_t pos)
{
    uint32_t reg = pos < 6u ? a->reg[SQR3] : pos < 12u ? a->reg[SQR2] : a->reg[SQR1];
    return (uint8_t)((reg >> (5u * (pos % 6u))) & 0x1Fu);
}

static uint32_t sample_half(uint8_t ch)
{
    uint32_t reg = ch < 10u ? a->reg[SMPR2] : a->reg[SMPR1];
    return smp_half[(reg >> (3u * (ch % 10u))) & 7u];
}

static uint32_t scan_length(void)
{
    return (a->reg[CR1] & CR1_SCAN) ? ((a->reg[SQR1] >> 20) & 0xFu) + 1u : 1u;
}

static void begin(uint64_t at)
{
    uint8_t ch = channel_at(a->pos);
    a->conv_start = at;
    a->conv_end = at + (sample_half(ch) + 25u) * half_cycle();
}

static void start_scan(uint64_t at)
{
    if (model_adc_hz() > 14000000u)
        model_violation("ADC clock %u Hz (14 MHz at most)", model_adc_hz());
    if (model.now < a->cal_until)
        model_violation("ADC conversion started during calibration");
    a->scanning = true;
    a->pos = 0;
    begin(at);
}

static void dma_transfer(uint16_t v)
{
    if (!(a->dma_ccr & DMA_EN))
        return;
    if (a->dma_cpar != ADC_DR_ADDR)
        model_violation("DMA1 channel 1 reads 0x%08x, not ADC1_DR", a->dma_cpar);
    uint32_t index = a->dma_cndtr - a->dma_left;
    uint32_t at = a->dma_cmar + ((a->dma_ccr & DMA_MINC) ? 2u * index : 0u);
    uint16_t *dst = (uint16_t *)(uintptr_t)at; /* the test program is linked without PIE */
    *dst = v;
    if (--a->dma_left == 0u)
        a->dma_left = (a->dma_ccr & DMA_CIRC) ? a->dma_cndtr : 0u;
    if (a->dma_left == 0u)
        a->dma_ccr &= ~DMA_EN;
}

static void finish_conversion(void)
{
    uint8_t ch = channel_at(a->pos);
    uint64_t hold = a->conv_start + sample_half(ch) * half_cycle();
    uint16_t v = a->analog ? a->analog(ch, hold) : 0u;
    a->reg[DR] = v & 0xFFFu;
    a->reg[SR] |= 2u; /* EOC */
    if (ch < 18u)
        a->hold[ch] = hold;
    a->conversions++;
    if (a->reg[CR2] & CR2_DMA)
        dma_transfer((uint16_t)(v & 0xFFFu));
    uint64_t end = a->conv_end;
    if (++a->pos < scan_length()) {
        begin(end);
    } else if (a->reg[CR2] & CR2_CONT) {
        a->pos = 0;
        begin(end);
    } else {
        a->scanning = false;
        /* TRGO edges that came during the scan were ignored */
        uint64_t e;
        while ((e = tim3_trgo_after(a->trgo_used)) < end) {
            a->trgo_used = e;
            a->triggers_ignored++;
        }
    }
}

static bool triggered(void)
{
    uint32_t cr2 = a->reg[CR2];
    return (cr2 & CR2_ADON) && (cr2 & CR2_EXTTRIG) && EXTSEL(cr2) == EXTSEL_TIM3_TRGO;
}

void adc_sync(void)
{
    for (;;) {
        if (a->scanning) {
            if (a->conv_end > model.now)
                return;
            finish_conversion();
            continue;
        }
        if (!triggered())
            return;
        uint64_t e = tim3_trgo_after(a->trgo_used);
        if (e > model.now)
            return;
        a->trgo_used = e;
        start_scan(e + 2u * 2u * half_cycle()); /* tlatr: 2 ADC cycles (datasheet) */
    }
}

uint64_t adc_next(void)
{
    if (a->scanning)
        return a->conv_end;
    if (triggered())
        return tim3_trgo_after(a->trgo_used);
    return MODEL_NEVER;
}

void adc_reset(uint8_t why)
{
    (void)why;
    for (int i = 0; i < 20; i++)
        a->reg[i] = 0;
    a->dma_ccr = a->dma_cndtr = a->dma_cpar = a->dma_cmar = a->dma_left = 0;
    a->scanning = false;
    a->cal_until = 0;
    a->trgo_used = model.now;
}

uint32_t adc_read(uint32_t off, uint32_t bytes)
{
    (void)bytes;
    uint32_t k = off / 4u;
    if (k == CR2) {
        uint32_t v = a->reg[CR2];
        if (model.now >= a->cal_until)
            v &= ~(CR2_CAL | CR2_RSTCAL);
        return v;
    }
    if (k == DR) {
        a->reg[SR] &= ~2u;
        return a->reg[DR];
    }
    if (k < 20u)
        return a->reg[k];
    model_violation("ADC1 read at +0x%x", off);
    return 0;
}

static void write_cr2(uint32_t v)
{
    uint32_t was = a->reg[CR2];
    if (!(was & CR2_ADON) && (v & CR2_ADON)) {
        a->reg[CR2] = v & ~(CR2_CAL | CR2_RSTCAL | CR2_SWSTART); /* power up only */
        return;
    }
    if ((v & (CR2_CAL | CR2_RSTCAL)) && (v & CR2_ADON)) {
        a->cal_until = model.now + ((v & CR2_CAL) ? 83u : 2u) * 2u * half_cycle();
        if (a->scanning)
            model_violation("ADC calibration started during a conversion");
    }
    if ((v & CR2_EXTTRIG) && EXTSEL(v) == EXTSEL_TIM3_TRGO && !triggered())
        a->trgo_used = model.now; /* edges from now on */
    a->reg[CR2] = v & ~CR2_SWSTART;
    bool start = (v & CR2_ADON) && (((v & CR2_SWSTART) && (v & CR2_EXTTRIG) &&
                                     EXTSEL(v) == EXTSEL_SWSTART) ||
                                    v == was); /* ADON written again alone: a start */
    if (start && !a->scanning)
        start_scan(model.now);
}

void adc_write(uint32_t off, uint32_t v, uint32_t bytes)
{
    (void)bytes;
    uint32_t k = off / 4u;
    if (k == CR2)
        write_cr2(v);
    else if (k < 20u && k != DR)
        a->reg[k] = v;
    else
        model_violation("ADC1 write of 0x%x at +0x%x", v, off);
}

uint32_t dma_read(uint32_t off, uint32_t bytes)
{
    (void)bytes;
    switch (off) {
    case 0x08:
        return a->dma_ccr;
    case 0x0C:
        return a->dma_left;
    case 0x10:
        return a->dma_cpar;
    case 0x14:
        return a->dma_cmar;
    default:
        model_violation("DMA1 read at +0x%x (only channel 1 is modelled)", off);
        return 0;
    }
}

void dma_write(uint32_t off, uint32_t v, uint32_t bytes)
{
    (void)bytes;
    if (off >= 0x0Cu && off <= 0x14u && (a->dma_ccr & DMA_EN)) {
        model_violation("DMA1 channel 1 set up while enabled");
        return;
    }
    switch (off) {
    case 0x08:
        if ((v & DMA_EN) && !(a->dma_ccr & DMA_EN)) {
            a->dma_left = a->dma_cndtr;
            if ((v & (1u << 4)) || ((v >> 8) & 3u) != 1u || ((v >> 10) & 3u) != 1u)
                model_violation("DMA1 channel 1 CCR 0x%x: not 16-bit peripheral to memory", v);
        }
        a->dma_ccr = v & 0x7FFFu;
        break;
    case 0x0C:
        a->dma_cndtr = v & 0xFFFFu;
        break;
    case 0x10:
        a->dma_cpar = v;
        break;
    case 0x14:
        a->dma_cmar = v;
        break;
    default:
        model_violation("DMA1 write of 0x%x at +0x%x (only channel 1 is modelled)", v, off);
        break;
    }
}
