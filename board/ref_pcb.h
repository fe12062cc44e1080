/* board/ref_pcb.h - what every reference board shares: one PCB design, an STM32F103C8
 * (64 KiB flash, 20 KiB RAM; the CB's 128 KiB works too), fitted per variant. Included by
 * each board/<name>/board_pins.h after it has chosen its fittings: BOARD_POSITION_POT
 * (potentiometer or encoder), BOARD_PHOTO (homing switches or none) and
 * BOARD_CURRENT_MA_FS (the shunt). Model number, range, limits and bus defaults are in
 * board/<name>/board.c, the single source of those (it takes BOARD_PHOTO from
 * board_pins.h). */
#ifndef BOARD_REF_PCB_H
#define BOARD_REF_PCB_H

#if !defined(BOARD_POSITION_POT) || !defined(BOARD_PHOTO) || !defined(BOARD_CURRENT_MA_FS)
#error "board_pins.h chooses BOARD_POSITION_POT, BOARD_PHOTO and BOARD_CURRENT_MA_FS first"
#endif

#define BOARD_HSE_HZ 8000000u /* crystal; the clock code falls back to HSI without it */

/* Required of the PCB, because the firmware cannot do it: from reset until the
 * bootloader's first instructions drive them (boot_main.c), and all the while the ROM
 * bootloader runs (BOOT0 high), every pin is a floating input. So:
 *   - PA12 (RS485 DE and /RE): 10 kOhm to GND. A floating DE can switch the driver on
 *     and hold the shared bus for every other servo on it;
 *   - PB0 (the bridge's nSLEEP): 10 kOhm to GND, and PA6, PA7 (IN1, IN2): 10 kOhm to GND,
 *     so the bridge stays asleep and its inputs low: the motor never moves by itself;
 *   - BOOT0: 10 kOhm to GND.
 * From the bootloader's first call on, gpio_init() drives DE and nSLEEP low. */

/* Bus: USART1 through a half-duplex RS485 transceiver (DE and /RE tied together). */
#define BOARD_PIN_UART_TX PIN('A', 9)
#define BOARD_PIN_UART_RX PIN('A', 10)
#define BOARD_PIN_RS485_DE PIN('A', 12)   /* high: driver on */
#define BOARD_PIN_RS485_TERM PIN('B', 1)  /* high: 120 ohm terminator switched in */

/* Motor: two-input H-bridge (IN1/IN2, coast when both low), PWM on TIM3 CH1/CH2. */
#define BOARD_PIN_PWM_A PIN('A', 6)     /* TIM3_CH1 -> IN1: positive direction */
#define BOARD_PIN_PWM_B PIN('A', 7)     /* TIM3_CH2 -> IN2: negative direction */
#define BOARD_PIN_DRIVER_EN PIN('B', 0) /* high: bridge awake (nSLEEP) */
#define BOARD_PWM_HZ 20000u
#define BOARD_MOTOR_INVERT 0

/* Analog inputs (ADC1 channel = PAn for n < 8), 3.3 V full scale. */
#define BOARD_ADC_CURRENT 2u        /* PA2: shunt amplifier output */
#define BOARD_ADC_SUPPLY 3u         /* PA3: supply divider */
#define BOARD_ADC_TEMP 4u           /* PA4: MCP9700A-type sensor, 500 mV at 0 C, 10 mV/C */
#define BOARD_SUPPLY_MV_FS 19800u /* mV at ADC full scale: 10k/2k divider */
#define BOARD_TEMP_MV_AT_0C 500u
#define BOARD_TEMP_UV_PER_DC 1000u  /* 10 mV per degree = 1000 uV per 0.1 C */

/* Current: low-side shunt and amplifier (x 20) on BOARD_ADC_CURRENT; the shunt fitted
 * sets BOARD_CURRENT_MA_FS. The shunt carries current only during the PWM's on-time;
 * the port samples it for 13.5 ADC cycles (1.1 us at 72 MHz) at the middle of the
 * on-time (motor.c), so the amplifier must drive PA2 directly: output impedance with
 * any series resistor below 10 kOhm, and no filter slower than 0.5 us (an RC of e.g.
 * 100 Ohm and 2.2 nF at most): a slower one averages the on-time with the off-time.
 * The other inputs are sampled for 41.5 cycles: sources below 30 kOhm. */

/* What the board needs of its port (HAL_CAP_*, hal.h): its board.c states it, the
 * STM32 port reports it (hal_capabilities). */
#include "hal.h"

#define BOARD_FITTINGS                                                                     \
    ((BOARD_PHOTO ? HAL_CAP_PHOTO : 0u) | HAL_CAP_TERMINATOR |                               \
     (BOARD_POSITION_POT ? HAL_CAP_POT : HAL_CAP_ENCODER))

#if BOARD_POSITION_POT
/* Position: potentiometer on the output shaft, ADC1 channel 0 (PA0); its electrical
 * span over the ADC full scale sets the counts (struct board counts_per_rev per turn). */
#define BOARD_ADC_POT 0u
#define BOARD_POT_SPAN_DDEG 3000u /* 300 degrees from 0 V to 3.3 V */
#define BOARD_POT_INVERT 0
#else
/* Position: quadrature encoder on TIM2 CH1/CH2 (encoder mode 3, 4 counts per line);
 * struct board counts_per_rev = lines x 4 x gear ratio. */
#define BOARD_PIN_ENC_A PIN('A', 0) /* TIM2_CH1 */
#define BOARD_PIN_ENC_B PIN('A', 1) /* TIM2_CH2 */
#define BOARD_ENCODER_INVERT 0
#endif

#if BOARD_PHOTO
/* Homing photo switches (slotted, open collector, pulled up: high = light path
 * interrupted). */
#define BOARD_PIN_PHOTO1 PIN('B', 12)
#define BOARD_PIN_PHOTO2 PIN('B', 13)
#define BOARD_PHOTO_ACTIVE_HIGH 1
#endif

#endif
