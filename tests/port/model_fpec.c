/* model_fpec.c - the flash memory interface (RM0008 §3.3.3; the sequences are PM0075's):
 *   - LOCK and the key sequence: KEY1 then KEY2 unlocks FLASH_CR; any other write to
 *     KEYR (a wrong key, or any key while unlocked) locks it until the next reset;
 *   - PG: the CPU programs one half-word by writing it into the array (a byte or word
 *     write is a bus error); the FPEC first checks the half-word is erased: if not, and
 *     the value is not 0x0000, the program is skipped with PGERR;
 *   - PER, AR, STRT: erase the page holding AR (the part's page size: 1 or 2 KiB);
 *   - WRPRTERR: a program or erase of a page the option bytes protect is skipped;
 *   - BSY for the operation's time (knobs), then EOP; EOP, PGERR, WRPRTERR clear on
 *     writing 1. AR is not writable while BSY.
 * Writing FLASH_CR or AR, or the array, while BSY is a violation (the rule:
 * never touch a busy controller), as is any read of the array during an operation that
 * never ends (the CPU would stall for ever). Faults to inject: BSY stuck, a long
 * operation, PGERR, protection, EOP late, and a power cut at any operation. */
#include <string.h>

#include "model.h"
#include "model_parts.h"

#define KEY1 0x45670123u
#define KEY2 0xCDEF89ABu
#define SR_BSY (1u << 0)
#define SR_PGERR (1u << 2)
#define SR_WRPRTERR (1u << 4)
#define SR_EOP (1u << 5)
#define CR_PG (1u << 0)
#define CR_PER (1u << 1)
#define CR_MER (1u << 2)
#define CR_OPTPG (1u << 4)
#define CR_OPTER (1u << 5)
#define CR_STRT (1u << 6)
#define CR_LOCK (1u << 7)

enum { OP_NONE, OP_PROGRAM, OP_ERASE, OP_FOREIGN };

static struct model_fpec *const f = &model.fpec;

static bool busy(void)
{
    return f->op != OP_NONE;
}

uint32_t fpec_wait_states(void)
{
    return f->acr & 7u;
}

static uint32_t rnd(void)
{
    f->rng ^= f->rng << 13;
    f->rng ^= f->rng >> 17;
    f->rng ^= f->rng << 5;
    return f->rng;
}

static uint32_t page_of(uint32_t addr)
{
    return (addr - MODEL_FLASH_BASE) / f->page_bytes;
}

static bool protected_at(uint32_t addr)
{
    uint32_t block = (addr - MODEL_FLASH_BASE) / 4096u; /* 4 KiB per WRPR bit */
    return block < 32u && !((f->wrpr >> block) & 1u);
}

static bool in_flash(uint32_t addr)
{
    return addr >= MODEL_FLASH_BASE && addr - MODEL_FLASH_BASE < f->flash_kib * 1024u &&
           addr - MODEL_FLASH_BASE < MODEL_FLASH_BYTES;
}

/* The operation's effect on the array; torn: as a power cut in its middle leaves it. */
static void apply(bool torn)
{
    if (f->op == OP_PROGRAM) {
        uint8_t *p = &f->mem[f->op_addr - MODEL_FLASH_BASE];
        uint16_t old = (uint16_t)(p[0] | (p[1] << 8));
        uint32_t keep = torn ? f->op_value | rnd() : f->op_value; /* torn: bits left undone */
        uint16_t v = (uint16_t)(old & keep);
        p[0] = (uint8_t)v;
        p[1] = (uint8_t)(v >> 8);
        f->programs++;
    } else if (f->op == OP_ERASE) {
        uint8_t *p = &f->mem[page_of(f->op_addr) * f->page_bytes];
        for (uint32_t i = 0; i < f->page_bytes; i++)
            p[i] = torn ? (uint8_t)(p[i] | rnd()) : 0xFFu;
        f->erases++;
    }
}

/* An erase or program begins: count it; a power cut of the CLEAN kind strikes now. */
static void start(uint8_t op, uint32_t addr, uint16_t value, uint64_t ticks)
{
    f->ops++;
    if (f->cut_at && f->ops == f->cut_at && f->cut_kind == MODEL_CUT_CLEAN)
        model_stop(MODEL_EXIT_POWER_CUT);
    f->op = op;
    f->op_addr = addr;
    f->op_value = value;
    f->op_end = f->stuck ? MODEL_NEVER : model.now + ticks;
    f->sr |= SR_BSY;
}

void model_fpec_busy(uint64_t ticks)
{
    f->op = OP_FOREIGN;
    f->op_end = model.now + ticks;
    f->sr |= SR_BSY;
}

void fpec_sync(void)
{
    if (!busy() || model.now < f->op_end)
        return;
    bool cut = f->op != OP_FOREIGN && f->cut_at && f->ops == f->cut_at;
    apply(cut && f->cut_kind == MODEL_CUT_TORN);
    f->op = OP_NONE;
    f->sr = (f->sr & ~SR_BSY) | SR_EOP;
    f->cr &= ~CR_STRT;
    f->lag_left = f->flag_lag;
    if (cut)
        model_stop(MODEL_EXIT_POWER_CUT);
}

uint64_t fpec_next(void)
{
    return busy() ? f->op_end : MODEL_NEVER;
}

void fpec_reset(uint8_t why)
{
    (void)why;
    if (busy() && f->op != OP_FOREIGN)
        apply(true); /* a reset in the middle of an operation leaves it torn */
    f->op = OP_NONE;
    f->acr = 0x30u; /* prefetch buffer on, zero wait states */
    f->cr = CR_LOCK;
    f->sr = 0;
    f->ar = 0;
    f->key_state = 0;
    f->key_locked = false;
    f->lag_left = 0;
    if (why == MODEL_RESET_POWER)
        f->ops = 0;
}

uint32_t fpec_read(uint32_t off, uint32_t bytes)
{
    (void)bytes;
    switch (off) {
    case 0x00:
        return f->acr;
    case 0x0C:
        if (!busy() && f->lag_left) {
            f->lag_left--;
            return f->sr & ~SR_EOP;
        }
        return f->sr;
    case 0x10:
        return f->cr;
    case 0x20:
        return f->wrpr;
    default:
        model_violation("FLASH read at +0x%x, which the port does not use", off);
        return 0;
    }
}

static void write_keyr(uint32_t v)
{
    if (f->key_locked) {
        model_violation("FLASH_KEYR written after a wrong key (bus error, locked until reset)");
        return;
    }
    if (!(f->cr & CR_LOCK)) {
        model_violation("FLASH_KEYR written while unlocked: locked until reset");
        f->key_locked = true;
        f->cr |= CR_LOCK;
        return;
    }
    if (f->key_state == 0u && v == KEY1) {
        f->key_state = 1;
    } else if (f->key_state == 1u && v == KEY2) {
        f->key_state = 0;
        f->cr &= ~CR_LOCK;
    } else {
        model_violation("wrong FPEC key 0x%08x: locked until reset", v);
        f->key_locked = true;
    }
}

static void write_cr(uint32_t v)
{
    if (busy())
        model_violation("FLASH_CR written (0x%x) while BSY%s", v,
                        (v & CR_LOCK) ? ": a busy controller relocked" : "");
    if (f->cr & CR_LOCK) {
        if (v & ~CR_LOCK)
            model_violation("FLASH_CR written (0x%x) while locked: ignored", v);
        return;
    }
    if (v & (CR_MER | CR_OPTPG | CR_OPTER))
        model_violation("FLASH_CR 0x%x: mass erase or option bytes", v);
    if ((v & CR_PG) && (v & CR_PER))
        model_violation("FLASH_CR: PG and PER together");
    bool strt = (v & CR_STRT) && !(f->cr & CR_STRT);
    f->cr = v;
    if (!strt || busy())
        return;
    if (!(v & CR_PER)) {
        model_violation("STRT without PER");
        return;
    }
    if (!in_flash(f->ar)) {
        model_violation("erase at 0x%08x, outside the part's %u KiB", f->ar, f->flash_kib);
        return;
    }
    if (protected_at(f->ar)) {
        f->sr |= SR_WRPRTERR;
        return;
    }
    start(OP_ERASE, f->ar, 0, f->erase_ticks);
}

void fpec_write(uint32_t off, uint32_t v, uint32_t bytes)
{
    (void)bytes;
    switch (off) {
    case 0x00:
        f->acr = (f->acr & ~0x1Fu) | (v & 0x1Fu);
        break;
    case 0x04:
        write_keyr(v);
        break;
    case 0x08:
        model_violation("FLASH_OPTKEYR written: the port never touches the option bytes");
        break;
    case 0x0C:
        f->sr &= ~(v & (SR_EOP | SR_PGERR | SR_WRPRTERR));
        break;
    case 0x10:
        write_cr(v);
        break;
    case 0x14:
        if (busy()) {
            model_violation("FLASH_AR written (0x%08x) while BSY: ignored", v);
            break;
        }
        f->ar = v;
        break;
    default:
        model_violation("FLASH write of 0x%x at +0x%x, which the port does not use", v, off);
        break;
    }
}

/* A read of the array by the driver (the core reads it directly): during an operation
 * the CPU stalls until it ends. */
uint32_t fpec_array_read(uint32_t off, uint32_t bytes)
{
    if (busy()) {
        if (f->op_end == MODEL_NEVER)
            model_violation("flash read at 0x%08x while BSY never falls: the CPU stalls for "
                            "ever",
                            MODEL_FLASH_BASE + off);
        else
            model_run(f->op_end - model.now);
    }
    const uint8_t *p = &f->mem[off];
    uint32_t v = 0;
    for (uint32_t i = 0; i < bytes; i++)
        v |= (uint32_t)p[i] << (8u * i);
    return v;
}

void fpec_array_write(uint32_t off, uint32_t v, uint32_t bytes)
{
    uint32_t addr = MODEL_FLASH_BASE + off;
    if (busy()) {
        model_violation("flash written at 0x%08x while BSY", addr);
        return;
    }
    if ((f->cr & CR_LOCK) || !(f->cr & CR_PG)) {
        model_violation("flash written at 0x%08x without PG (bus error)", addr);
        return;
    }
    if (bytes != 2u || (addr & 1u)) {
        model_violation("flash programmed %u bytes wide at 0x%08x (half-words only)", bytes,
                        addr);
        return;
    }
    if (!in_flash(addr)) {
        model_violation("program at 0x%08x, outside the part's %u KiB", addr, f->flash_kib);
        return;
    }
    if (protected_at(addr)) {
        f->sr |= SR_WRPRTERR;
        return;
    }
    const uint8_t *p = &f->mem[off];
    uint16_t old = (uint16_t)(p[0] | (p[1] << 8));
    if (f->pgerr_next || (old != 0xFFFFu && v != 0u)) {
        if (f->pgerr_next)
            f->pgerr_next--;
        f->ops++; /* counted (a cut there leaves the half-word as it is) */
        f->sr |= SR_PGERR;
        return;
    }
    start(OP_PROGRAM, addr, (uint16_t)v, f->program_ticks);
}
