/* model.c - the bus of the register models (model.h): address decoding, clock gating,
 * virtual time and its events, resets and the exits back to the test. */
#define _GNU_SOURCE
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "model.h"
#include "model_parts.h"

struct model model;
uint32_t model_basepri;

/* A register block: its address range, its model, the clock enable it needs (reg 0
 * AHBENR, 1 APB2ENR, 2 APB1ENR; NO_GATE: always clocked). */
#define NO_GATE 0xFFu
struct block {
    uint32_t base, size;
    uint32_t (*read)(uint32_t off, uint32_t bytes);
    void (*write)(uint32_t off, uint32_t value, uint32_t bytes);
    uint8_t gate_reg, gate_bit;
    const char *name;
};

static uint32_t gpio_a_read(uint32_t off, uint32_t b) { return gpio_read(off, b); }
static uint32_t gpio_b_read(uint32_t off, uint32_t b) { return gpio_read(0x400u + off, b); }
static uint32_t gpio_c_read(uint32_t off, uint32_t b) { return gpio_read(0x800u + off, b); }
static void gpio_a_write(uint32_t off, uint32_t v, uint32_t b) { gpio_write(off, v, b); }
static void gpio_b_write(uint32_t off, uint32_t v, uint32_t b) { gpio_write(0x400 + off, v, b); }
static void gpio_c_write(uint32_t off, uint32_t v, uint32_t b) { gpio_write(0x800 + off, v, b); }
static uint32_t tim2_read(uint32_t off, uint32_t b) { return tim_read(off, b); }
static uint32_t tim3_read(uint32_t off, uint32_t b) { return tim_read(0x400u + off, b); }
static void tim2_write(uint32_t off, uint32_t v, uint32_t b) { tim_write(off, v, b); }
static void tim3_write(uint32_t off, uint32_t v, uint32_t b) { tim_write(0x400u + off, v, b); }

static uint32_t f_size_read(uint32_t off, uint32_t bytes)
{
    if (off != 0 || bytes != 2u)
        model_violation("F_SIZE read at +%u, %u bytes wide (a half-word at +0)", off, bytes);
    return model.fpec.flash_kib;
}

static void read_only(uint32_t off, uint32_t value, uint32_t bytes)
{
    (void)bytes;
    model_violation("write of 0x%x to read-only memory (+0x%x)", value, off);
}

static const struct block blocks[] = {
    {0x40000000u, 0x400u, tim2_read, tim2_write, 2, 0, "TIM2"},
    {0x40000400u, 0x400u, tim3_read, tim3_write, 2, 1, "TIM3"},
    {0x40003000u, 0x400u, iwdg_read, iwdg_write, NO_GATE, 0, "IWDG"},
    {0x40010800u, 0x400u, gpio_a_read, gpio_a_write, 1, 2, "GPIOA"},
    {0x40010C00u, 0x400u, gpio_b_read, gpio_b_write, 1, 3, "GPIOB"},
    {0x40011000u, 0x400u, gpio_c_read, gpio_c_write, 1, 4, "GPIOC"},
    {0x40012400u, 0x400u, adc_read, adc_write, 1, 9, "ADC1"},
    {0x40013800u, 0x400u, usart_read, usart_write, 1, 14, "USART1"},
    {0x40020000u, 0x400u, dma_read, dma_write, 0, 0, "DMA1"},
    {0x40021000u, 0x400u, rcc_read, rcc_write, NO_GATE, 0, "RCC"},
    {0x40022000u, 0x400u, fpec_read, fpec_write, NO_GATE, 0, "FLASH"},
    {MODEL_FLASH_BASE, MODEL_FLASH_BYTES, fpec_array_read, fpec_array_write, NO_GATE, 0,
     "flash"},
    {MODEL_F_SIZE_ADDR, 4u, f_size_read, read_only, NO_GATE, 0, "F_SIZE"},
    {0xE000E000u, 0x1000u, cpu_read, cpu_write, NO_GATE, 0, "SCS"},
};

/* The peripherals' blocks are 1 KiB each from PERIPH_BASE: found by index. The search
 * through the table was most of the port tests' time (a driver's wait loop polls a
 * register for a long while). */
#define PERIPH_BASE 0x40000000u
#define PERIPH_SLOTS 0x90u /* to the FLASH interface's block, 0x40022000 */
static const struct block *block_at(uintptr_t addr)
{
    static const struct block *slot[PERIPH_SLOTS];
    static bool indexed;
    if (!indexed) {
        for (size_t i = 0; i < sizeof blocks / sizeof blocks[0]; i++)
            if (blocks[i].base >= PERIPH_BASE && blocks[i].size == 0x400u &&
                (blocks[i].base - PERIPH_BASE) / 0x400u < PERIPH_SLOTS)
                slot[(blocks[i].base - PERIPH_BASE) / 0x400u] = &blocks[i];
        indexed = true;
    }
    if (addr >= PERIPH_BASE && (addr - PERIPH_BASE) / 0x400u < PERIPH_SLOTS)
        return slot[(addr - PERIPH_BASE) / 0x400u];
    for (size_t i = 0; i < sizeof blocks / sizeof blocks[0]; i++)
        if (addr >= blocks[i].base && addr - blocks[i].base < blocks[i].size)
            return &blocks[i];
    return NULL;
}

void model_violation(const char *fmt, ...)
{
    if (model.violations++ == 0) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(model.violation, sizeof model.violation, fmt, ap);
        va_end(ap);
    }
}

uint64_t model_cycle_ticks(void)
{
    return MODEL_HZ / model_sysclk_hz();
}

/* Catch every part up with model.now. */
static void sync_all(void)
{
    rcc_sync();
    fpec_sync();
    usart_sync();
    iwdg_sync();
    cpu_sync();
    tim_sync();
    adc_sync();
}

static uint64_t next_event(void)
{
    uint64_t e = MODEL_NEVER, n;
#define EARLIEST(part)                                                                   \
    n = part##_next();                                                                   \
    if (n < e)                                                                           \
        e = n;
    EARLIEST(rcc)
    EARLIEST(fpec)
    EARLIEST(usart)
    EARLIEST(iwdg)
    EARLIEST(cpu)
    EARLIEST(tim)
    EARLIEST(adc)
#undef EARLIEST
    return e;
}

/* Move time to t, stopping at every event on the way (and taking the interrupts it
 * raises); at the deadline, stop the code under test. */
static void advance_to(uint64_t t)
{
    for (uint32_t guard = 0;; guard++) {
        if (guard > 100000000u) {
            model_violation("the models never reach tick %llu", (unsigned long long)t);
            model_stop(MODEL_EXIT_DEADLINE);
        }
        cpu_deliver();
        uint64_t e = next_event();
        if (e <= model.now)
            e = model.now + 1u; /* an event due now was just handled */
        uint64_t stop = e < t ? e : t;
        if (model.deadline && model.deadline <= stop) {
            if (model.deadline > model.now)
                model.now = model.deadline;
            sync_all();
            model_stop(MODEL_EXIT_DEADLINE);
        }
        if (e > t)
            break;
        model.now = e;
        sync_all();
    }
    if (t > model.now)
        model.now = t;
    sync_all();
    cpu_deliver();
}

void model_run(uint64_t ticks)
{
    advance_to(model.now + ticks);
}

/* One access: its cycles pass first (interrupts may come in between), then the access. */
static const struct block *access_begin(uintptr_t addr, uint32_t bytes, bool write)
{
    model.accesses++;
    advance_to(model.now + MODEL_ACCESS_CYCLES * model_cycle_ticks());
    if (model.on_access)
        model.on_access(addr, write);
    const struct block *b = block_at(addr);
    if (b == NULL) {
        model_violation("access to 0x%lx, which no model covers", (unsigned long)addr);
        return NULL;
    }
    if (bytes != 4u && b->base != MODEL_FLASH_BASE && b->base != MODEL_F_SIZE_ADDR &&
        b->base != 0xE000E000u)
        model_violation("%s accessed %u bytes wide at +0x%lx (the drivers use words)",
                        b->name, bytes, (unsigned long)(addr - b->base));
    if (b->gate_reg != NO_GATE && !rcc_clock_on(b->gate_reg, b->gate_bit)) {
        model_violation("%s accessed with its clock off (+0x%lx)", b->name,
                        (unsigned long)(addr - b->base));
        return NULL;
    }
    return b;
}

uint32_t model_read(uintptr_t addr, uint32_t bytes)
{
    const struct block *b = access_begin(addr, bytes, false);
    return b ? b->read((uint32_t)(addr - b->base), bytes) : 0u;
}

void model_write(uintptr_t addr, uint32_t value, uint32_t bytes)
{
    const struct block *b = access_begin(addr, bytes, true);
    if (b)
        b->write((uint32_t)(addr - b->base), value, bytes);
}

void model_wfi(void)
{
    /* Sleep until something happens: the next event (an interrupt follows it, or not:
     * WFI may return early, which the code must cope with anyway). */
    uint64_t e = next_event();
    if (e == MODEL_NEVER)
        e = model.now + MODEL_MS(1);
    advance_to(e > model.now ? e : model.now + 1u);
}

void model_jump(uint32_t sp, uint32_t pc)
{
    model.jump_sp = sp;
    model.jump_pc = pc;
    model_stop(MODEL_EXIT_JUMP);
}

void model_basepri_max(uint32_t v)
{
    if (v != 0 && (model_basepri == 0 || v < model_basepri))
        model_basepri = v;
}

void model_basepri_set(uint32_t v)
{
    model_basepri = v;
    cpu_deliver(); /* lowering it lets a pending interrupt in */
}

void model_stop(uint8_t why)
{
    model.cpu.handler = 0;
    model_basepri = 0;
    model.deadline = 0;
    if (model.exit == NULL) {
        fprintf(stderr, "model: the code under test stopped (%u) with no model_catch()\n",
                why);
        abort();
    }
    jmp_buf *jb = model.exit;
    model.exit = NULL;
    longjmp(*jb, why);
}

void model_reset(uint8_t why)
{
    model.resets++;
    model_basepri = 0;
    rcc_reset(why);
    fpec_reset(why);
    gpio_reset(why);
    usart_reset(why);
    iwdg_reset(why);
    cpu_reset(why);
    tim_reset(why);
    adc_reset(why);
}

/* The flash array lives at its STM32 address: the core reads it through the pointers
 * hal_flash_page() returns. The CPU's view is read-only (a stray write faults, as it
 * would on the MCU); the FPEC model writes through a second view of the same memory. */
static void map_flash(void)
{
    int fd = memfd_create("model-flash", 0);
    if (fd < 0 || ftruncate(fd, MODEL_FLASH_BYTES) != 0)
        abort();
    void *ro = mmap((void *)(uintptr_t)MODEL_FLASH_BASE, MODEL_FLASH_BYTES, PROT_READ,
                    MAP_SHARED | MAP_FIXED_NOREPLACE, fd, 0);
    void *rw = mmap(NULL, MODEL_FLASH_BYTES, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    if (ro != (void *)(uintptr_t)MODEL_FLASH_BASE || rw == MAP_FAILED) {
        fprintf(stderr, "model: cannot map the flash at 0x%08x\n", MODEL_FLASH_BASE);
        abort();
    }
    close(fd);
    model.fpec.mem = rw;
}

void model_init(void)
{
    uint8_t *mem = model.fpec.mem;
    memset(&model, 0, sizeof model);
    if (mem == NULL)
        map_flash();
    else
        model.fpec.mem = mem;
    memset(model.fpec.mem, 0xFF, MODEL_FLASH_BYTES);
    model.rcc.crystal = true;
    model.rcc.pll_locks = true;
    model.fpec.flash_kib = 64;
    model.fpec.page_bytes = 1024;
    model.fpec.program_ticks = MODEL_US(52) + MODEL_US(1) / 2u; /* 52.5 us typical */
    model.fpec.erase_ticks = MODEL_MS(20);
    model.fpec.wrpr = 0xFFFFFFFFu;
    model.fpec.rng = 0x2545F491u;
    model.iwdg.lsi_hz = 40000;
    model.gpio.watch = 0xFF;
    model.usart.de_pin = 0xFF;
    model_reset(MODEL_RESET_POWER);
}
