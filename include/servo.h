/* servo.h - one servo: all of its mutable state in one struct, its interrupt entry point
 * and its main-loop step. Several servos may live in one host process. */
#ifndef SERVO_H
#define SERVO_H

#include <stdint.h>

#include "board.h"
#include "frame_rx.h"
#include "link.h"
#include "loader.h"
#include "motion.h"
#include "regs.h"
#include "safety.h"
#include "store.h"
#include "traj.h"
#include "update.h"

struct hal;

/* The write held by REG WRITE until ACTION (§4.4). */
struct held_write {
    uint8_t addr;
    uint8_t n; /* 0: nothing held */
    uint8_t data[REGS_SIZE];
};

/* Member order is code size: the 16-bit Thumb-2 loads and stores reach only small
 * offsets (bytes < 32, half-words < 64, words < 128), so what the main loop touches most
 * (the register table, the flags, the motion state) comes first and the big buffers (the
 * receiver, the trajectory, the held write) last. */
struct servo {
    struct hal *hal;
    const struct board *board;
    struct regs regs;
    struct loader loader; /* update mode or the application; a restart due (loader.h) */
    uint8_t confirm_due; /* an answer has left the wire, or BOOT_CONFIRM_US have passed */
    uint8_t confirmed;  /* boot_confirm() has nothing left to do (boot.h) */
    uint32_t start_us;  /* power-up of the application */
    struct safety safety;
    struct motion motion;
    struct link link;
    struct update update; /* §10 session */
    struct store store;
    struct held_write held;
    struct traj traj;
    struct frame_rx rx;
};

/* The servo's board description. A firmware image is built for one board
 * (SERVO_BOARD_FIXED, cmake/stm32.cmake): there it is that constant object, whose fields
 * the link-time optimiser folds, dropping what only other boards need (the base's
 * relative goals on the arm, homing on the base). On the host, where servos of several
 * boards share one process, the servo's own. */
#ifdef SERVO_BOARD_FIXED
extern const struct board SERVO_BOARD_FIXED;
#endif
static inline const struct board *servo_board(const struct servo *s)
{
#ifdef SERVO_BOARD_FIXED
    (void)s;
    return &SERVO_BOARD_FIXED;
#else
    return s->board;
#endif
}

/* Power-up: factory table with the stored EEPROM registers on top, settings in force,
 * receiver empty, motor off. Then servo_poll() confirms the start (boot_confirm) once
 * its first answer has left the wire, or after BOOT_CONFIRM_US. */
void servo_init(struct servo *s, const struct board *b, struct hal *hal);

/* Interrupt context: the UART received one byte. */
void servo_rx_isr(struct servo *s, uint8_t byte);

/* The same, for a port whose interrupt has the byte's arrival time at hand (cheaper than
 * hal_clock_us() in the handler's context: the STM32 port's USART1 interrupt). */
static inline void servo_rx_isr_at(struct servo *s, uint8_t byte, uint32_t now_us)
{
    frame_rx_byte(&s->rx, byte, now_us);
}

/* Main loop, both modes (the application, and update mode when the bootloader, or the
 * host's servo_power_on(), started that): do whatever is due (a control tick, send an answer,
 * dispatch the next frame, commit a changed setting). Never blocks. */
void servo_poll(struct servo *s);

#endif
