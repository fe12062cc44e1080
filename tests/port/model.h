/* model.h - register models of the STM32F103, written from RM0008 (and the Cortex-M3
 * TRM for SysTick, NVIC and SCB), on which the port's own driver files (hal/stm32f1/)
 * run on the host. Included ahead of every port file the host compiles (-include): it
 * defines REG_READ/REG_WRITE and the CPU_ instructions that stm32f1_regs.h leaves
 * overridable, so each access reaches model_read()/model_write() with its address and
 * width, and the models give it its side effects (reading SR then DR clears RXNE, a
 * key sequence unlocks the FPEC, a write into flash with PG set programs it).
 *
 * Time is virtual, in ticks of 1/576 MHz, so that every clock of the port (72, 64, 24
 * and 8 MHz, the ADC's, the LSI's, every USART bit) is a whole number of ticks. It
 * advances by MODEL_ACCESS_CYCLES CPU cycles at every access (about what the code
 * around an access costs: the port's wait loops run 3 to 6 instructions per access),
 * and when a test calls model_run(). Code between accesses takes no time. Interrupts
 * (SysTick, USART1) are taken before an access when their priority beats BASEPRI and
 * the handler running, as the NVIC takes them between instructions.
 *
 * A driver doing what RM0008 forbids (or what issue 30 asks the port never to do, such
 * as writing the FPEC while it is busy) does not stop the model: it is recorded as a
 * violation, and every test asserts that there is none. What the models leave out is
 * listed in hal/stm32f1/README.md ("What the register models prove"). Each peripheral's
 * file owns its part of struct model; the test sets the knobs (what the board and the
 * part are, which fault to inject) and reads the logs. */
#ifndef PORT_MODEL_H
#define PORT_MODEL_H

#include <setjmp.h>
#include <stdbool.h>
#include <stdint.h>

/* ---- What the port's files see ---- */
uint32_t model_read(uintptr_t addr, uint32_t bytes);
void model_write(uintptr_t addr, uint32_t value, uint32_t bytes);
void model_wfi(void);
void model_jump(uint32_t sp, uint32_t pc) __attribute__((noreturn));
void model_basepri_max(uint32_t v);
void model_basepri_set(uint32_t v);
extern uint32_t model_basepri;

#define REG_READ(r) model_read((uintptr_t) & (r), (uint32_t)sizeof(r))
#define REG_WRITE(r, v) model_write((uintptr_t) & (r), (uint32_t)(v), (uint32_t)sizeof(r))
#define CPU_DSB() __asm__ volatile("" ::: "memory")
#define CPU_ISB() __asm__ volatile("" ::: "memory")
#define CPU_WFI() model_wfi()
#define CPU_BASEPRI_GET(out) ((out) = model_basepri)
#define CPU_BASEPRI_MAX(v) model_basepri_max(v)
#define CPU_BASEPRI_SET(v) model_basepri_set(v)
#define CPU_JUMP(sp, pc) model_jump(sp, pc)

/* ---- Time ---- */
#define MODEL_HZ 576000000ull /* ticks per second */
#define MODEL_US(us) ((uint64_t)(us) * (MODEL_HZ / 1000000u))
#define MODEL_MS(ms) ((uint64_t)(ms) * (MODEL_HZ / 1000u))
#define MODEL_NEVER UINT64_MAX
#define MODEL_ACCESS_CYCLES 4u

/* ---- What the test sees ---- */

/* Why the code under test stopped: the value model_catch() returns the second time. */
enum model_exit {
    MODEL_RUNNING,
    MODEL_EXIT_DEADLINE,  /* the time the test set (model.deadline) was reached */
    MODEL_EXIT_JUMP,      /* the bootloader branched to an application (CPU_JUMP) */
    MODEL_EXIT_RESET,     /* a system reset: software (SYSRESETREQ) or the IWDG */
    MODEL_EXIT_POWER_CUT, /* the power went at the flash operation the test chose */
};

enum model_reset {
    MODEL_RESET_POWER, /* power-on: every register at its reset value, flash kept */
    MODEL_RESET_SOFT,  /* SYSRESETREQ (the port's fault path and hal_restart) */
    MODEL_RESET_IWDG,  /* the independent watchdog ran out */
};

/* How a power cut at a flash operation leaves it (as hal/host/flash_sim.h). */
enum model_cut {
    MODEL_CUT_CLEAN, /* the operation never happened */
    MODEL_CUT_DONE,  /* it completed, then the power went */
    MODEL_CUT_TORN,  /* a program left some bits undone, an erase some bits erased */
};

/* A GPIO pin as the board sees it. */
enum model_pin {
    MODEL_PIN_FLOATING, /* input without pull, or analog: nothing drives the net */
    MODEL_PIN_PULL_DOWN,
    MODEL_PIN_PULL_UP,
    MODEL_PIN_LOW,  /* general-purpose output driven low */
    MODEL_PIN_HIGH, /* general-purpose output driven high */
    MODEL_PIN_ALT,  /* alternate-function output: a peripheral drives it */
};

#define MODEL_FLASH_BASE 0x08000000u
#define MODEL_FLASH_BYTES (64u * 1024u)
#define MODEL_F_SIZE_ADDR 0x1FFFF7E0u /* flash size register, KiB (RM0008 §30.1) */

/* Reset and clock control (RM0008 §7.3). */
struct model_rcc {
    bool crystal;   /* knob: the 8 MHz crystal starts (in 2 ms) */
    bool pll_locks; /* knob: the PLL locks (in 200 us) */
    uint32_t cr, cfgr, csr, ahbenr, apb2enr, apb1enr;
    uint64_t hse_ready_at, pll_ready_at;
};

/* Flash interface (RM0008 §3.3.3, PM0075): the part, faults to inject, the registers. */
struct model_fpec {
    /* knobs */
    uint32_t flash_kib;  /* what F_SIZE reads: 64 (STM32F103x8), 128 (xB), 256 (xC) ... */
    uint32_t page_bytes; /* the erase granule: 1024 (up to 128 KiB) or 2048 */
    uint64_t program_ticks, erase_ticks;
    bool stuck;          /* BSY never falls again once set */
    uint32_t flag_lag;   /* SR reads after BSY falls that still lack EOP */
    uint32_t pgerr_next; /* the next n programs fail with PGERR */
    uint32_t wrpr;       /* option bytes: bit n clear = pages 4n..4n+3 write-protected */
    uint32_t cut_at;     /* the power goes at this erase or program (1-based; 0 never) */
    uint8_t cut_kind;    /* enum model_cut */
    /* state */
    uint32_t acr, cr, sr, ar, key_state;
    bool key_locked;     /* a wrong key: locked until reset */
    uint8_t op;          /* 0 none, 1 program, 2 erase, 3 foreign (model_fpec_busy) */
    uint32_t op_addr;
    uint16_t op_value;
    uint64_t op_end;
    uint32_t lag_left;
    uint32_t ops;        /* erases and programs started since power-on */
    uint32_t programs, erases; /* ever */
    uint32_t rng;
    uint8_t *mem;        /* MODEL_FLASH_BYTES, the model's writable view of the array */
};

/* GPIO ports A to C (RM0008 §9.2). */
struct model_gpio {
    uint32_t crl[3], crh[3], odr[3];
    uint32_t ext_driven[3], ext_high[3]; /* knob: what the board drives on inputs */
    uint8_t watch;                       /* knob: the pin whose edges are logged */
    uint32_t edges;
    struct {
        uint64_t at;
        uint8_t state; /* enum model_pin */
    } edge[256];
};

/* USART1 (RM0008 §27.6) and the bus behind its transceiver. */
#define MODEL_TX_LOG 4096u
#define MODEL_RX_QUEUE 8192u
struct model_usart {
    uint8_t de_pin; /* knob: the transceiver's driver enable (and /RE) */
    bool echo;      /* knob: the transceiver hears what it sends (single wire) */
    uint32_t sr, rdr, brr, cr1, cr2, cr3;
    uint32_t sr_seen; /* flags an SR read saw since the last DR access (0: no read) */
    bool sr_read;
    bool tdr_full, shifting, idle_frame, shift_de_ok;
    uint8_t tdr, shift;
    uint64_t shift_start, shift_end;
    uint32_t rx_head, rx_tail;
    struct {
        uint64_t start; /* start bit begins */
        uint64_t bit;   /* the sender's bit time */
        uint8_t byte;
    } rx[MODEL_RX_QUEUE];
    uint64_t wire_free; /* the host may start its next byte from here */
    uint32_t rx_unheard; /* bytes that arrived while our driver enable was high */
    uint32_t tx_len;
    struct model_tx {
        uint64_t start, end; /* start bit begins, stop bit ends */
        uint8_t byte;
        bool de_all_along;   /* the driver enable was high from start to end */
    } tx[MODEL_TX_LOG];
};

/* Independent watchdog (RM0008 §19.4). */
struct model_iwdg {
    uint32_t lsi_hz;  /* knob: 30 to 60 kHz (40 nominal) */
    bool hw_option;   /* knob: option bytes start it in hardware at reset */
    bool on, access;
    uint32_t pr, rlr;          /* in force */
    uint32_t pr_new, rlr_new;  /* written, crossing into the LSI domain until *_at */
    uint64_t pr_at, rlr_at;
    uint64_t expires;
    uint32_t feeds;
};

/* Cortex-M3 SysTick, NVIC (USART1 only) and SCB. */
struct model_cpu {
    uint32_t basepri;
    uint8_t handler; /* 0 thread mode, else the priority of the handler running */
    uint32_t st_csr, st_rvr;
    uint64_t st_base;  /* the counter was written 0 (or enabled) at st_base */
    uint64_t st_wraps; /* wraps already pended */
    bool st_pending;
    uint32_t iser[2];
    uint8_t ip[64];
    uint8_t shp[12];
    uint32_t vtor;
    uint32_t storm;    /* handler entries at one instant (storm_at) */
    uint64_t storm_at;
};

/* TIM2 (encoder) and TIM3 (PWM), registers by offset / 4 (RM0008 §15.4). */
struct model_tim {
    uint32_t reg[2][20];
    uint64_t base3;       /* TIM3's counter was 0 at base3 */
    uint32_t ccr_old[4];  /* TIM3 CCRx in force before its last write (preload) */
    uint64_t ccr_at[4];   /* when it was written */
};

/* ADC1 (RM0008 §11) and DMA1 channel 1 (§13), which serves it. */
struct model_adc {
    uint16_t (*analog)(uint8_t channel, uint64_t tick); /* knob: the board's inputs */
    uint32_t reg[20];
    uint32_t dma_ccr, dma_cndtr, dma_cpar, dma_cmar, dma_left;
    uint64_t cal_until;
    bool scanning;
    uint32_t pos;          /* conversion of the scan in progress */
    uint64_t conv_start, conv_end;
    uint64_t trgo_used;    /* the last TIM3 TRGO edge taken (or ignored) */
    uint32_t conversions, triggers_ignored;
    uint64_t hold[18]; /* per channel: the hold instant of its last sample */
};

struct model {
    uint64_t now;      /* ticks */
    uint64_t deadline; /* knob: stop the code under test here (0: never) */
    void (*on_access)(uintptr_t addr, bool write); /* knob: told of every access first */
    jmp_buf *exit;     /* where model_stop() goes */
    uint32_t jump_sp, jump_pc;
    uint32_t resets;
    uint32_t accesses;
    uint32_t violations;
    char violation[200]; /* the first one */
    struct model_rcc rcc;
    struct model_fpec fpec;
    struct model_gpio gpio;
    struct model_usart usart;
    struct model_iwdg iwdg;
    struct model_cpu cpu;
    struct model_tim tim;
    struct model_adc adc;
};

extern struct model model;

/* A fresh board: the flash erased, every knob at its default (crystal and PLL work,
 * LSI 40 kHz, an STM32F103x8: 64 KiB in 1 KiB pages, program 52.5 us, erase 20 ms, no
 * write protection), then power-on. */
void model_init(void);

/* A reset of the kind given: registers to their reset values, the reset flags set, the
 * flash kept (an operation in progress is left torn), time and logs kept. */
void model_reset(uint8_t why);

/* Run code under test: model_catch() returns 0, then enum model_exit when it stops. */
#define model_catch(jb) (model.exit = &(jb), setjmp(jb))
void model_stop(uint8_t why) __attribute__((noreturn));

/* Let ticks pass: events and interrupts in between. */
void model_run(uint64_t ticks);

void model_violation(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* Clocks in force, from the RCC's registers. */
uint32_t model_sysclk_hz(void);
uint32_t model_pclk1_hz(void);
uint32_t model_pclk2_hz(void);
uint32_t model_tim_apb1_hz(void);
uint32_t model_adc_hz(void);

/* FPEC: BSY set for ticks from now, as if an operation were running. */
void model_fpec_busy(uint64_t ticks);

/* GPIO */
enum model_pin model_pin_state(uint8_t pin); /* pin: hal_stm32f1.h PIN() */
void model_pin_drive(uint8_t pin, int level); /* 1 high, 0 low, -1 let go */

/* USART1: the bit rate BRR gives now (0: disabled); a host on the bus sending n bytes
 * back to back at baud from now (or once the bus is free); what the servo sent. */
uint32_t model_usart_bps(void);
void model_wire_send(const uint8_t *bytes, uint32_t n, uint32_t baud);
uint32_t model_wire_take(uint32_t *from, uint8_t *out, uint32_t max);

/* TIM2: n quadrature edges on TI1/TI2 (positive: the encoder turns forward). TIM3:
 * channel ch's reference output (OCxREF) at tick t. */
void model_encoder_edges(int32_t n);
bool model_tim3_ref(uint32_t ch, uint64_t t);
uint32_t model_tim3_counter(uint64_t t);

/* The flash array as the CPU reads it, at its address. */
static inline const uint8_t *model_flash(uint32_t addr)
{
    return (const uint8_t *)(uintptr_t)addr;
}

#endif
