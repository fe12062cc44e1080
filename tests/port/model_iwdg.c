/* model_iwdg.c - the independent watchdog (RM0008 §19.4): KR 0xCCCC starts it (from
 * RLR's reset value 0xFFF, LSI / 4), 0xAAAA reloads the counter from RLR, 0x5555 opens
 * PR and RLR for writing (any other key closes them again). A written PR or RLR crosses
 * into the LSI domain for up to 5 LSI periods (PVU, RVU), then applies from the next
 * reload. The counter runs down at LSI / (4 << PR), /256 at most (PR 6 and 7); at 0
 * the chip resets. Knobs: the LSI's frequency (30 to 60 kHz), the hardware watchdog
 * option (running from reset). */
#include "model.h"
#include "model_parts.h"

#define SR_PVU (1u << 0)
#define SR_RVU (1u << 1)

static struct model_iwdg *const w = &model.iwdg;

static uint64_t lsi_ticks(void)
{
    return MODEL_HZ / w->lsi_hz;
}

/* Values crossing into the LSI domain apply once they have. */
static void settle(void)
{
    if (model.now >= w->pr_at)
        w->pr = w->pr_new;
    if (model.now >= w->rlr_at)
        w->rlr = w->rlr_new;
}

static void reload(void)
{
    settle();
    uint32_t div = 4u << (w->pr < 6u ? w->pr : 6u); /* PR 110 and 111: both /256 */
    w->expires = model.now + (uint64_t)(w->rlr + 1u) * div * lsi_ticks();
}

void iwdg_reset(uint8_t why)
{
    (void)why;
    w->on = w->hw_option;
    w->access = false;
    w->pr = w->pr_new = 0;
    w->rlr = w->rlr_new = 0xFFFu;
    w->pr_at = w->rlr_at = 0;
    w->expires = MODEL_NEVER;
    if (w->on)
        reload();
}

uint32_t iwdg_read(uint32_t off, uint32_t bytes)
{
    (void)bytes;
    if (off == 0x0Cu)
        return (model.now < w->pr_at ? SR_PVU : 0u) | (model.now < w->rlr_at ? SR_RVU : 0u);
    if (off == 0x04u)
        return w->pr;
    if (off == 0x08u)
        return w->rlr;
    model_violation("IWDG read at +0x%x", off);
    return 0;
}

void iwdg_write(uint32_t off, uint32_t v, uint32_t bytes)
{
    (void)bytes;
    switch (off) {
    case 0x00:
        w->access = (v & 0xFFFFu) == 0x5555u;
        if ((v & 0xFFFFu) == 0xCCCCu && !w->on) {
            w->on = true;
            reload();
        } else if ((v & 0xFFFFu) == 0xAAAAu && w->on) {
            reload();
            w->feeds++;
        }
        break;
    case 0x04:
    case 0x08: {
        bool pr = off == 0x04u;
        if (!w->access) {
            model_violation("IWDG %s written without the key 0x5555", pr ? "PR" : "RLR");
            break;
        }
        if (model.now < (pr ? w->pr_at : w->rlr_at))
            model_violation("IWDG %s written while its last value is still crossing",
                            pr ? "PR" : "RLR");
        uint64_t at = model.now + 5u * lsi_ticks();
        if (pr) {
            w->pr_new = v & 7u;
            w->pr_at = at;
        } else {
            w->rlr_new = v & 0xFFFu;
            w->rlr_at = at;
        }
        break;
    }
    default:
        model_violation("IWDG write of 0x%x at +0x%x", v, off);
        break;
    }
}

uint64_t iwdg_next(void)
{
    return w->on ? w->expires : MODEL_NEVER;
}

void iwdg_sync(void)
{
    if (w->on && model.now >= w->expires) {
        model_reset(MODEL_RESET_IWDG);
        model_stop(MODEL_EXIT_RESET);
    }
}
