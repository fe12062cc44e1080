/* board/finger/board_pins.h - the reference finger board (1 A limit):
 * STM32F103C8 (64 KiB flash, 20 KiB RAM; a GD32F103C8 fits too) pin map and analog
 * scaling. Model number, range, limits and bus defaults are in board/boards.c
 * (board_finger), the single source of those; this file holds only what the port needs
 * to drive the hardware. board/README.md has what every reference board shares. */
#ifndef BOARD_PINS_H
#define BOARD_PINS_H

#define BOARD_HSE_HZ 8000000u /* crystal; the clock code falls back to HSI without it */

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

/* Position: potentiometer on the output shaft, ADC1 channel 0 (PA0); its electrical
 * span over the ADC full scale sets the counts (struct board counts_per_rev per turn). */
#define BOARD_POSITION_POT 1
#define BOARD_ADC_POT 0u
#define BOARD_POT_SPAN_DDEG 3000u /* 300 degrees from 0 V to 3.3 V */
#define BOARD_POT_INVERT 0

/* Analog inputs (ADC1 channel = PAn for n < 8), 3.3 V full scale. */
#define BOARD_ADC_CURRENT 2u        /* PA2: shunt amplifier output */
#define BOARD_ADC_SUPPLY 3u         /* PA3: supply divider */
#define BOARD_ADC_TEMP 4u           /* PA4: MCP9700A-type sensor, 500 mV at 0 C, 10 mV/C */
#define BOARD_CURRENT_MA_FS 1650u /* mA at ADC full scale: 100 mOhm shunt x 20 */
#define BOARD_SUPPLY_MV_FS 19800u /* mV at ADC full scale: 10k/2k divider */
#define BOARD_TEMP_MV_AT_0C 500u
#define BOARD_TEMP_UV_PER_DC 1000u  /* 10 mV per degree = 1000 uV per 0.1 C */

/* Homing photo switches (slotted, open collector, pulled up: high = light path
 * interrupted). */
#define BOARD_PHOTO 1
#define BOARD_PIN_PHOTO1 PIN('B', 12)
#define BOARD_PIN_PHOTO2 PIN('B', 13)
#define BOARD_PHOTO_ACTIVE_HIGH 1

#endif
