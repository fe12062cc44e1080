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

/* Member order is code size: the 16-bit Thumb-2 loads and stores reach only small
 * offsets (bytes < 32, half-words < 64, words < 128), so what the main loop touches most
 * (the register table, the flags, the motion state) comes first and the big buffers (the
 * receiver, the trajectory, the held write) last. */
struct servo {
    struct hal *hal;
    const struct board *board;
    struct regs regs;
    uint8_t fw_version; /* register 2: the running image's version */
    uint8_t in_loader;  /* running update mode (loader.h), not the application */
    uint8_t restart;    /* restart once the answer in progress has left the wire */
    uint8_t confirm_due; /* an answer has left the wire, or BOOT_CONFIRM_US have passed */
    uint8_t confirmed;  /* boot_confirm() has nothing left to do (boot.h) */
    uint8_t hung;       /* host model: the image hangs at start (servo_power_on) */
    uint32_t start_us;  /* power-up of the application (or of the hang) */
    struct safety safety;
    struct motion motion;
    struct link link;
    struct update update; /* §10 session */
    struct store store;
    struct held_write held;
    struct traj traj;
    struct frame_rx rx;
};

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

/* Main loop, both modes (the application, and update mode when servo_power_on() or the
 * bootloader started that): do whatever is due (a control tick, send an answer,
 * dispatch the next frame, commit a changed setting). Never blocks. */
void servo_poll(struct servo *s);

/* Power-up as the MCU does it with its bootloader (host harnesses): install a staged
 * update and count the start (boot_start, boot.h), then start the application with the
 * watchdog running, or stay in update mode (loader.h) when no valid image is installed
 * or it has BOOT_STARTS_MAX unconfirmed starts.
 *
 * The host image model: whatever the image's bytes, "starting" it runs this core, with
 * register 2 from its info block; except an image whose info block's reserved byte is
 * IMAGE_HOST_HANG (image.h), which stands for a build that hangs at start: nothing runs
 * and nothing feeds the watchdog, which resets the servo (hal_restart) after
 * SERVO_WATCHDOG_US, as the IWDG would. */
#define SERVO_WATCHDOG_US 250000u /* hal/stm32f1/iwdg.c: 250 ms nominal */
void servo_power_on(struct servo *s, const struct board *b, struct hal *hal);

/* Host harnesses: one main-loop step of whatever servo_power_on() started (servo_poll(),
 * or the watchdog model of a hung image). */
void servo_step(struct servo *s);

#endif
