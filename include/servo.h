/* servo.h - one servo: all of its mutable state in one struct, its interrupt entry point
 * and its main-loop step. Several servos may live in one host process. */
#ifndef SERVO_H
#define SERVO_H

#include <stdint.h>

#include "board.h"
#include "frame_rx.h"
#include "link.h"
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

struct servo {
    struct hal *hal;
    const struct board *board;
    struct frame_rx rx;
    struct regs regs;
    struct link link;
    struct held_write held;
    struct traj traj;
    struct store store;
    struct motion motion;
    struct safety safety;
    struct update update; /* §10 session */
    uint8_t live_err; /* ERR bits 0-3 and 6, owned by the safety layer */
    uint8_t fw_version; /* register 2: the running image's version */
    uint8_t in_loader;  /* running update mode (loader.h), not the application */
    uint8_t restart;    /* restart once the answer in progress has left the wire */
};

/* Power-up: factory table with the stored EEPROM registers on top, settings in force,
 * receiver empty, motor off. */
void servo_init(struct servo *s, const struct board *b, struct hal *hal);

/* Interrupt context: the UART received one byte. */
void servo_rx_isr(struct servo *s, uint8_t byte);

/* The same, for a port whose interrupt has the byte's arrival time at hand (cheaper than
 * hal_clock_us() in the handler's context: the STM32 port's USART1 interrupt). */
static inline void servo_rx_isr_at(struct servo *s, uint8_t byte, uint32_t now_us)
{
    frame_rx_byte(&s->rx, byte, now_us);
}

/* Main loop: do whatever is due (send an answer, dispatch the next frame). Never blocks. */
void servo_poll(struct servo *s);

/* Power-up as the MCU does it with its bootloader (host harnesses): install a staged
 * update (boot.h), then start the application, or stay in update mode (loader.h) when no
 * valid image is installed. */
void servo_power_on(struct servo *s, const struct board *b, struct hal *hal);

/* Main loop step of whichever servo_power_on() started. */
void servo_step(struct servo *s);

#endif
