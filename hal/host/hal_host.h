/* hal_host.h - the host port of the HAL: a virtual clock that tests advance by hand and
 * a UART that logs every byte the servo sends with the time its start bit begins. */
#ifndef HAL_HOST_H
#define HAL_HOST_H

#include <stdbool.h>
#include <stdint.h>

#include "flash_sim.h"
#include "board.h"
#include "hal.h"
#include "motor_sim.h"

#define HAL_HOST_TX_LOG 8192u
#define HAL_HOST_COUNTS_PER_REV 16384u /* matches every reference board */

/* The virtual clock starts 10 s before the 32-bit microsecond clock wraps (71.6 min), so
 * every test, servo-sim session and benchmark crosses the wrap early on, as Linux starts
 * jiffies 5 min before theirs: time arithmetic that is not wrap-safe fails in tests, not
 * after an hour in a robot. */
#define HAL_HOST_CLOCK_START (0u - 10000000u)

struct hal_tx_byte {
    uint32_t start_us; /* start bit begins */
    uint32_t end_us;   /* stop bit ends */
    uint32_t baud;
    uint8_t byte;
};

struct hal {
    uint32_t now_us;
    uint32_t baud;
    uint32_t tx_end_us;
    bool tx_active;
    bool stalled;       /* a flash erase holds the main loop until stall_until_us */
    int32_t irq_depth;  /* > 0 while the core has interrupts masked */
    uint32_t sends;     /* hal_uart_send() calls */
    uint32_t baud_sets; /* hal_uart_set_baud() calls */
    uint32_t uart_clock_hz; /* 0: the UART makes every rate exactly; else the clock of a
                             * 16x-oversampling UART (a fall-back clock, for a test) */
    /* A page erase stalls the STM32F1's CPU on every flash read for 20-40 ms, so the main
     * loop (in flash) stops while the receive interrupt (in RAM) goes on. 0 (the default):
     * an erase takes no time. Else node_step() runs no pass for this long after an
     * erase; the pass that erased finishes at once (at most a frame better than silicon,
     * which would finish it after the stall). */
    uint32_t erase_stall_us;
    uint32_t stall_until_us;
    uint32_t log_len;   /* bytes logged; the log keeps the last HAL_HOST_TX_LOG */
    struct flash_sim flash; /* the store's flash; survives a simulated reboot */
    struct motor_sim motor; /* the plant: keeps turning across a reboot */
    uint16_t supply_mv;     /* sensors, set by tests */
    uint16_t current_extra_ma; /* fault injection: a current spike on top of the motor's */
    int16_t temperature_dc;
    uint8_t photo;          /* switch bits when photo_sim is off */
    bool photo_sim;         /* switches follow the motor: */
    uint8_t uid[HAL_UID_BYTES]; /* hal_uid(): the harness sets it per node */
    double sw1_deg, sw2_deg; /* switch 1 reads high beyond sw1 (away from sw2), 2 beyond sw2 */
    bool termination;
    uint8_t capabilities;   /* HAL_CAP_* the port reports (hal_capabilities) */
    bool restart_requested; /* hal_restart() was called; the harness reboots */
    bool power_reset;       /* the last reboot was a power cycle, not a restart/watchdog */
    bool image_hung;        /* servo_power_on() started an image that hangs (below) */
    bool watchdog_started;
    uint32_t watchdog_feeds;
    uint32_t hung_since_us; /* image_hung since: the watchdog resets it SERVO_WATCHDOG_US on */
    struct hal_tx_byte log[HAL_HOST_TX_LOG];
};

/* Clock at HAL_HOST_CLOCK_START, UART idle at 9600, empty log, blank flash. */
void hal_host_init(struct hal *h);

/* The i-th byte ever sent (i < log_len, and not older than HAL_HOST_TX_LOG bytes). */
const struct hal_tx_byte *hal_host_tx(const struct hal *h, uint32_t i);

/* Start and end of byte i of a transmission that began at t0 (10 bits per byte). */
uint32_t hal_host_byte_start(uint32_t t0, uint32_t baud, uint32_t i);
uint32_t hal_host_byte_end(uint32_t t0, uint32_t baud, uint32_t i);

/* Fit the plant to a reference board: for boards with photo switches, switch 1 at the
 * zero (negative) side at 0 degrees, switch 2 at the board's travel (arm: 420 degrees),
 * and the shaft starting at 90 degrees, between them. */
void hal_host_attach_board(struct hal *h, const struct board *b);

/* Power cycle: the UART and clock state go, the flash stays (a cut is cleared). */
void hal_host_reboot(struct hal *h);

/* Synthetic application images: hal_host_image_build(), hal_host_image_stamp(). */
#include "image_build.h"

/* Make img (len bytes, from hal_host_image_build) an image that hangs at start in the
 * host model (servo_power_on): its info block's reserved byte IMAGE_HOST_HANG, its CRC
 * stamped again, as tools/fwstamp.py does to a file. */
void hal_host_image_hang(uint8_t *img, uint32_t len);

/* What a programmer does at the factory: erase the application slot and write img into
 * it directly (no power cut, no wear counted). */
void hal_host_program_app(struct hal *h, const uint8_t *img, uint32_t len);

/* The factory image of board b: HAL_HOST_FACTORY_BYTES built by hal_host_image_build()
 * at this build's version (SERVO_FW_VERSION, register 2), programmed into the
 * application slot. (image_host.c, library image_host.) */
#define HAL_HOST_FACTORY_BYTES (16u * 1024u)
void hal_host_program_factory(struct hal *h, const struct board *b);

/* Host model only (servo_power_on): an image whose info block's reserved byte
 * (IMAGE_OFF_RESERVED) is this stands for a build that hangs at start (tests make one by
 * setting the byte and stamping the image again, tools/fwstamp.py). The bootloader does
 * not look at the byte. */
#define IMAGE_HOST_HANG 0x48u /* 'H' */

struct servo;

/* Power-up as the MCU does it with its bootloader (host harnesses; power_on.c): install a staged
 * update and count the start (boot_start, boot.h), then start the application with the
 * watchdog running, or stay in update mode (loader.h) when no valid image is installed
 * or it has BOOT_STARTS_MAX unconfirmed starts.
 *
 * The host image model: whatever the image's bytes, "starting" it runs this core, with
 * register 2 from its info block; except an image whose info block's reserved byte is
 * IMAGE_HOST_HANG (below), which stands for a build that hangs at start: nothing runs
 * and nothing feeds the watchdog, which resets the servo (hal_restart) after
 * SERVO_WATCHDOG_US, as the IWDG would. */
#define SERVO_WATCHDOG_US 250000u /* hal/stm32f1/iwdg.c: 250 ms nominal */
void servo_power_on(struct servo *s, const struct board *b, struct hal *hal);

/* Host harnesses: one main-loop step of whatever servo_power_on() started (servo_poll(),
 * or the watchdog model of a hung image). */
void servo_step(struct servo *s);

#endif
