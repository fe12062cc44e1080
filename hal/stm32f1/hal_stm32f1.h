/* hal_stm32f1.h - the STM32F103 port: its one struct hal, the board configuration it
 * reads (board/<name>/board_pins.h, with defaults and checks here), and the entry points
 * its files share. Only the port includes this; the core sees hal.h. */
#ifndef HAL_STM32F1_H
#define HAL_STM32F1_H

#include <stdbool.h>
#include <stdint.h>

#include "board.h"
#include "hal.h"
#include "stm32f1_regs.h"

/* A pin: port letter and number, e.g. PIN('A', 9). PIN_NONE: not fitted. */
#define PIN(port, n) ((uint8_t)((((port) - 'A') << 4) | (n)))
#define PIN_NONE 0xFFu

#include "board_pins.h"

/* ---- What a board must define, and the defaults of what it may leave out ---- */
#ifndef BOARD_PIN_RS485_DE
#error "board_pins.h must define BOARD_PIN_RS485_DE"
#endif
#ifndef BOARD_PIN_DRIVER_EN
#error "board_pins.h must define BOARD_PIN_DRIVER_EN"
#endif
#if !defined(BOARD_CURRENT_MA_FS) || !defined(BOARD_SUPPLY_MV_FS)
#error "board_pins.h must define the analog full scales"
#endif
#ifndef BOARD_POSITION_POT
#error "board_pins.h must define BOARD_POSITION_POT (0: encoder on TIM2, 1: potentiometer)"
#endif
#ifndef BOARD_HSE_HZ
#define BOARD_HSE_HZ 8000000u
#endif
#if BOARD_HSE_HZ != 8000000u
#error "the clock code multiplies an 8 MHz crystal by 9"
#endif
#ifndef BOARD_PIN_RS485_TERM
#define BOARD_PIN_RS485_TERM PIN_NONE
#endif
#ifndef BOARD_MOTOR_INVERT
#define BOARD_MOTOR_INVERT 0
#endif
#ifndef BOARD_ENCODER_INVERT
#define BOARD_ENCODER_INVERT 0
#endif
#ifndef BOARD_PIN_ENC_A
#define BOARD_PIN_ENC_A PIN_NONE
#define BOARD_PIN_ENC_B PIN_NONE
#endif
#ifndef BOARD_ADC_POT
#define BOARD_ADC_POT 0u
#endif
#ifndef BOARD_POT_SPAN_DDEG
#define BOARD_POT_SPAN_DDEG 3600u
#endif
#ifndef BOARD_POT_INVERT
#define BOARD_POT_INVERT 0
#endif
#ifndef BOARD_PHOTO
#define BOARD_PHOTO 0
#endif
#ifndef BOARD_PIN_PHOTO1
#define BOARD_PIN_PHOTO1 PIN_NONE
#define BOARD_PIN_PHOTO2 PIN_NONE
#endif
#ifndef BOARD_PHOTO_ACTIVE_HIGH
#define BOARD_PHOTO_ACTIVE_HIGH 1
#endif
#ifndef BOARD_TEMP_MV_AT_0C
#define BOARD_TEMP_MV_AT_0C 500u
#define BOARD_TEMP_UV_PER_DC 1000u
#endif
#ifndef BOARD_PWM_HZ
#define BOARD_PWM_HZ 20000u
#endif

/* Code and data that must keep working while the flash is busy (erase, program): the
 * CPU stalls on any flash read then, so whatever runs in an interrupt lives in RAM. The
 * linker script also puts the core's receive path (frame_rx.c, servo_rx_isr) there. */
#define RAMFUNC __attribute__((section(".ramfunc"), noinline))

/* Interrupt priorities (upper 4 bits used): SysTick above USART1, so the time base
 * keeps running inside the receive interrupt; hal_irq_save() masks USART1 only. */
#define PRIO_SYSTICK 0x40u
#define PRIO_USART1 0x80u

/* ADC1 scan order, the current first; TIM3 starts a scan every PWM period and DMA keeps
 * adc[] fresh (motor.c). */
enum { ADC_CURRENT, ADC_SUPPLY, ADC_TEMP, ADC_POT, ADC_SLOTS };
#define ADC_COUNT (BOARD_POSITION_POT ? 4u : 3u)

enum clock_source {
    CLOCK_HSE_PLL,     /* 8 MHz crystal x 9 = 72 MHz */
    CLOCK_HSI_PLL,     /* no crystal: HSI / 2 x 16 = 64 MHz */
    CLOCK_HSI,         /* no PLL either: 8 MHz */
    CLOCK_NO_RCC,      /* RCC reads 0 (QEMU's stm32vldiscovery): its fixed 24 MHz */
};

struct servo;

struct hal {
    /* Clock tree (clock_init). */
    uint32_t sysclk_hz, pclk1_hz, pclk2_hz, tim_apb1_hz;
    uint8_t clock_source; /* enum clock_source */
    volatile uint8_t tx_active; /* USART1 is sending: set under mask, cleared by TC */
    /* Time base: SysTick every 1 ms; the ISR adds 1000 (wraps with the clock). */
    volatile uint32_t tick_us;
    uint32_t tick_reload;    /* SysTick reload: cycles_per_us * 1000 - 1 */
    uint32_t cycles_per_us;
    /* USART1: the servo fed by the receive interrupt, the transmission in progress. */
    struct servo *servo;
    const uint8_t *tx_buf;
    uint16_t tx_len, tx_pos;
    uint32_t rx_overruns, rx_errors; /* bytes lost, bytes dropped (framing error) */
    uint32_t rx_half_bit_us; /* RXNE comes mid stop bit: the byte ends this much later */
    /* Motor and sensors. */
    const struct board *board;
    uint16_t pwm_period;    /* TIM3 counts per PWM period */
    uint16_t adc_lead;      /* TIM3 counts from the ADC's trigger to the current's hold */
    uint16_t enc_last;      /* TIM2 count at the last read */
    uint32_t enc_count;     /* 32-bit extension of TIM2, wraps */
    uint32_t pot_counts_fs; /* counts at the ADC full scale (potentiometer boards) */
    volatile uint16_t adc[ADC_SLOTS]; /* written by DMA */
    /* Flash: failed operations, for a debugger. */
    uint32_t flash_errors;
};

/* The port's one instance: the interrupt handlers reach it here. */
extern struct hal hal_stm32;

/* startup.c: the exception handlers' one way out: outputs safe, then a system reset. */
void fault_reset(void) __attribute__((noreturn));

/* clock.c: clock tree with fall-backs and flash wait states (main(), after gpio_init). */
void clock_init(struct hal *h);
/* clock.c: SysTick 1 kHz time base (hal_clock_us). */
void clock_tick_start(struct hal *h);

/* gpio.c: pin set-up (GPIO_IN_*, GPIO_OUT_*, GPIO_AF_*); PIN_NONE is ignored. */
void gpio_mode(uint8_t pin, uint32_t mode);

/* Drive an output pin; inline, so interrupt code stays in RAM. */
static inline void gpio_write(uint8_t pin, bool high)
{
    if (pin != PIN_NONE)
        REG_WRITE(GPIO(pin >> 4)->bsrr, (1u << (pin & 15u)) << (high ? 0u : 16u));
}

static inline bool gpio_read(uint8_t pin)
{
    return pin != PIN_NONE && ((REG_READ(GPIO(pin >> 4)->idr) >> (pin & 15u)) & 1u);
}
/* gpio.c: every board output in its safe state (bridge off, driver enable low). */
void gpio_init(void);

/* uart.c: USART1 at the boot baud, receiver on, interrupt off until uart_start(). */
void uart_init(struct hal *h);
/* uart.c: from now on every received byte goes to servo_rx_isr(s, byte). */
void uart_start(struct hal *h, struct servo *s);

/* motor.c: PWM off, position sensor and ADC scan running. */
void motor_init(struct hal *h, const struct board *b);

/* Exception and interrupt handlers (vector table in startup.c). */
void reset_handler(void) __attribute__((noreturn));
void fault_handler(void);
void systick_handler(void);
void usart1_handler(void);

#endif
