/* model_tim.c - TIM2 and TIM3 (RM0008 §15), as far as the port uses them:
 *   - TIM3 counts up (edge-aligned) at the APB1 timer clock / (PSC + 1), from 0 to ARR;
 *     each channel's reference OCxREF follows its output compare mode: PWM mode 1 is
 *     active while CNT < CCRx, PWM mode 2 while CNT >= CCRx. With OCxPE a written CCRx
 *     takes effect at the next update event (the counter's overflow). TRGO (CR2.MMS) is
 *     the update event or one OCxREF, for the ADC's external trigger;
 *   - TIM2 in encoder mode 3 counts each edge of TI1 and TI2 up or down with the
 *     direction of the quadrature (CC1P inverts it), wrapping at ARR.
 * The registers are kept as written; the tests read them to check the configuration
 * (both channels' outputs enabled, preload, the PWM frequency, the trigger point). */
#include "model.h"
#include "model_parts.h"

enum { CR1, CR2, SMCR, DIER, SR, EGR, CCMR1, CCMR2, CCER, CNT, PSC, ARR, RCR, CCR1, CCR2,
       CCR3, CCR4 };
#define CR1_CEN (1u << 0)
#define CR1_DIR (1u << 4)
#define CR1_CMS (3u << 5)

static struct model_tim *const t = &model.tim;

static uint64_t count_ticks(void)
{
    return MODEL_HZ / (model_tim_apb1_hz() / (t->reg[1][PSC] + 1u));
}

uint32_t model_tim3_counter(uint64_t at)
{
    const uint32_t *r = t->reg[1];
    if (!(r[CR1] & CR1_CEN))
        return r[CNT];
    return (uint32_t)(((at - t->base3) / count_ticks()) % ((uint64_t)r[ARR] + 1u));
}

/* The period (counted from base3) tick at falls in. */
static uint64_t period_of(uint64_t at)
{
    uint64_t len = ((uint64_t)t->reg[1][ARR] + 1u) * count_ticks();
    return at < t->base3 ? 0u : (at - t->base3) / len;
}

/* TIM3 CCRx (ch 1..4) in force at tick at: with preload (OCxPE), a value written takes
 * effect at the next update event. */
static uint32_t ccr_at(uint32_t ch, uint64_t at)
{
    const uint32_t *r = t->reg[1];
    uint32_t ccmr = ch <= 2u ? r[CCMR1] : r[CCMR2];
    bool preload = (ccmr >> (((ch - 1u) & 1u) ? 11u : 3u)) & 1u;
    if (preload && (r[CR1] & CR1_CEN) && period_of(at) == period_of(t->ccr_at[ch - 1u]))
        return t->ccr_old[ch - 1u];
    return r[CCR1 + ch - 1u];
}

bool model_tim3_ref(uint32_t ch, uint64_t at)
{
    const uint32_t *r = t->reg[1];
    uint32_t ccmr = ch <= 2u ? r[CCMR1] : r[CCMR2];
    uint32_t mode = (ccmr >> (((ch - 1u) & 1u) ? 12u : 4u)) & 7u;
    uint32_t cnt = model_tim3_counter(at), ccr = ccr_at(ch, at);
    switch (mode) {
    case 6:
        return cnt < ccr;
    case 7:
        return cnt >= ccr;
    case 4:
        return false; /* forced inactive */
    case 5:
        return true; /* forced active */
    default:
        return false;
    }
}

/* The counter value at which TRGO rises in the period holding tick `when` (or none). */
static bool trgo_count(uint64_t when, uint32_t *at)
{
    const uint32_t *r = t->reg[1];
    uint32_t mms = (r[CR2] >> 4) & 7u;
    if (mms == 2u) { /* update: the counter overflows to 0 */
        *at = 0;
        return true;
    }
    if (mms < 4u)
        return false;
    uint32_t ch = mms - 3u, ccmr = ch <= 2u ? r[CCMR1] : r[CCMR2];
    uint32_t mode = (ccmr >> (((ch - 1u) & 1u) ? 12u : 4u)) & 7u, ccr = ccr_at(ch, when);
    if (mode == 6u && ccr > 0u && ccr <= r[ARR]) { /* PWM 1: rises at 0 */
        *at = 0;
        return true;
    }
    if (mode == 7u && ccr > 0u && ccr <= r[ARR]) { /* PWM 2: rises at CCR */
        *at = ccr;
        return true;
    }
    return false;
}

uint64_t tim3_trgo_after(uint64_t after)
{
    const uint32_t *r = t->reg[1];
    if (!(r[CR1] & CR1_CEN))
        return MODEL_NEVER;
    uint64_t ct = count_ticks(), len = ((uint64_t)r[ARR] + 1u) * ct;
    uint64_t p = after < t->base3 ? 0u : (after - t->base3) / len;
    for (uint32_t k = 0; k < 3u; k++, p++) { /* this period, or one of the next */
        uint64_t start = t->base3 + p * len;
        uint32_t at;
        if (trgo_count(start, &at) && start + at * ct > after)
            return start + at * ct;
    }
    return MODEL_NEVER;
}

void model_encoder_edges(int32_t n)
{
    uint32_t *r = t->reg[0];
    if (!(r[CR1] & CR1_CEN) || (r[SMCR] & 7u) != 3u)
        return;
    if (r[CCER] & (1u << 1)) /* CC1P: TI1 inverted, the count runs the other way */
        n = -n;
    int64_t span = (int64_t)r[ARR] + 1;
    int64_t cnt = ((int64_t)r[CNT] + n) % span;
    r[CNT] = (uint32_t)(cnt < 0 ? cnt + span : cnt);
}

void tim_reset(uint8_t why)
{
    (void)why;
    for (int i = 0; i < 2; i++) {
        for (int k = 0; k < 20; k++)
            t->reg[i][k] = 0;
        t->reg[i][ARR] = 0xFFFFu;
    }
    t->base3 = model.now;
}

uint32_t tim_read(uint32_t off, uint32_t bytes)
{
    (void)bytes;
    uint32_t i = off >> 10, k = (off & 0x3FFu) / 4u;
    if (k >= 20u) {
        model_violation("TIM%u read at +0x%x", i + 2u, off & 0x3FFu);
        return 0;
    }
    if (i == 1u && k == CNT)
        return model_tim3_counter(model.now);
    return t->reg[i][k];
}

void tim_write(uint32_t off, uint32_t v, uint32_t bytes)
{
    (void)bytes;
    uint32_t i = off >> 10, k = (off & 0x3FFu) / 4u;
    if (k >= 20u) {
        model_violation("TIM%u write at +0x%x", i + 2u, off & 0x3FFu);
        return;
    }
    if (k == CR1 && (v & (CR1_DIR | CR1_CMS)) && i == 1u)
        model_violation("TIM3 CR1 0x%x: the model counts up, edge-aligned", v);
    if (k == EGR) {
        if (v & 1u && i == 1u) /* UG: the counter restarts */
            t->base3 = model.now;
        return;
    }
    if (i == 1u && k >= CCR1 && k <= CCR4) { /* preload: the old value until the update */
        t->ccr_old[k - CCR1] = ccr_at(k - CCR1 + 1u, model.now);
        t->ccr_at[k - CCR1] = model.now;
    }
    if (i == 1u && k == CNT)
        t->base3 = model.now; /* (only 0 is ever written) */
    if (i == 1u && k == CR1 && (v & CR1_CEN) && !(t->reg[1][CR1] & CR1_CEN))
        t->base3 = model.now;
    t->reg[i][k] = v;
}

uint64_t tim_next(void)
{
    return MODEL_NEVER;
}

void tim_sync(void)
{
}
