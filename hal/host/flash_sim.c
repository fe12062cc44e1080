/* flash_sim.c - simulated flash with power-cut injection (see flash_sim.h). */
#include <string.h>

#include "flash_sim.h"

void flash_sim_init(struct flash_sim *f)
{
    memset(f, 0, sizeof *f);
    memset(f->mem, 0xFF, sizeof f->mem);
    f->powered = true;
    f->rng = 0x2545F491u;
}

void flash_sim_power_on(struct flash_sim *f)
{
    f->powered = true;
    f->ops = 0;
    f->cut_at = 0;
}

static uint16_t undefined_bits(struct flash_sim *f)
{
    f->rng ^= f->rng << 13;
    f->rng ^= f->rng >> 17;
    f->rng ^= f->rng << 5;
    return (uint16_t)f->rng;
}

/* Count one operation; returns 0 to do it, 1 when the power goes now. */
static int cut_now(struct flash_sim *f)
{
    if (!f->powered)
        return -1;
    f->ops++;
    if (f->cut_at && f->ops == f->cut_at) {
        f->powered = false;
        return 1;
    }
    return 0;
}

const uint8_t *flash_sim_page(struct flash_sim *f, uint8_t p)
{
    return f->mem[p];
}

bool flash_sim_erase(struct flash_sim *f, uint8_t p)
{
    int cut = cut_now(f);
    if (cut < 0 || p >= FLASH_SIM_PAGES)
        return false;
    if (cut && f->cut_kind == FLASH_CUT_CLEAN)
        return false;
    f->erases[p]++;
    f->writes[p]++;
    if (cut && f->cut_kind == FLASH_CUT_TORN) {
        /* Half-erased: every half-word has some bits set to 1, the others as they were. */
        for (uint16_t off = 0; off < HAL_FLASH_PAGE_BYTES; off += 2u) {
            uint16_t v = (uint16_t)(f->mem[p][off] | (f->mem[p][off + 1u] << 8));
            v |= undefined_bits(f);
            f->mem[p][off] = (uint8_t)v;
            f->mem[p][off + 1u] = (uint8_t)(v >> 8);
        }
        return false;
    }
    memset(f->mem[p], 0xFF, HAL_FLASH_PAGE_BYTES);
    return !cut;
}

bool flash_sim_program(struct flash_sim *f, uint8_t p, uint16_t off, uint16_t value)
{
    int cut = cut_now(f);
    if (cut < 0 || p >= FLASH_SIM_PAGES || (off & 1u) || off >= HAL_FLASH_PAGE_BYTES)
        return false;
    if (cut && f->cut_kind == FLASH_CUT_CLEAN)
        return false;
    if (p < HAL_FLASH_PAGES)
        f->programs++;
    f->writes[p]++;
    uint16_t old = (uint16_t)(f->mem[p][off] | (f->mem[p][off + 1u] << 8));
    uint16_t v = old & value; /* programming only clears bits */
    if (cut && f->cut_kind == FLASH_CUT_TORN)
        v = old & (value | undefined_bits(f)); /* some of the bits to clear stay 1 */
    f->mem[p][off] = (uint8_t)v;
    f->mem[p][off + 1u] = (uint8_t)(v >> 8);
    return !cut;
}
