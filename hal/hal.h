/* hal.h - the one interface between the portable servo core and an MCU (or the host).
 *
 * Every function takes the port's context pointer so that several servos can run in one
 * host process; a single-chip port keeps one static instance and ignores the pointer.
 * Each function says in which context the core calls it. A port implements all of them
 * (see hal/stm32f1/ for the MCU, hal/host/ for the host simulation).
 *
 * Interrupt contract: the port's UART receive interrupt calls servo_rx_isr() (servo.h)
 * once per received byte, or servo_rx_isr_at() with the byte's arrival time on the
 * hal_clock_us() scale if it has it cheaper. Nothing else in the core runs in interrupt
 * context.
 */
#ifndef HAL_H
#define HAL_H

#include <stdbool.h>
#include <stdint.h>

struct hal; /* defined by each port */

/* Monotonic microsecond clock, wrapping at 2^32. Any context. */
uint32_t hal_clock_us(struct hal *h);

/* Set the UART baud rate. Main loop only, never while a transmission is in progress. */
void hal_uart_set_baud(struct hal *h, uint32_t baud);

/* The bit rate hal_uart_set_baud(h, baud) would make on the clock in force: the UART's
 * divider only comes close, and a fall-back clock (an MCU whose crystal did not start)
 * cannot make the fastest rates at all. The core refuses a baud code whose rate this
 * misses by more than 2 % (link_baud_reachable). Main loop. */
uint32_t hal_uart_baud_achieved(const struct hal *h, uint32_t baud);

/* Start sending len bytes without blocking: assert the RS485 driver enable, then send.
 * The buffer stays valid and untouched until hal_uart_tx_busy() returns false.
 * Main loop only; never called while hal_uart_tx_busy() is true. */
void hal_uart_send(struct hal *h, const uint8_t *buf, uint16_t len);

/* True until the last stop bit of the last hal_uart_send() has left the shift register
 * (transmission complete) and the driver enable has been released. Main loop. */
bool hal_uart_tx_busy(struct hal *h);

/* Mask the interrupts that call into the core; returns the previous state for
 * hal_irq_restore(). Keep the masked section short. Main loop. */
uint32_t hal_irq_save(struct hal *h);
void hal_irq_restore(struct hal *h, uint32_t state);

/* Flash the core owns, in pages of HAL_FLASH_PAGE_BYTES numbered by the core (the port
 * maps them to addresses; the bootloader's own code is not among them):
 *   pages 0 .. HAL_FLASH_PAGES-1          the persistent store (store.c)
 *   HAL_PAGE_APP .. +HAL_SLOT_PAGES-1     the application slot: the image that runs
 *   HAL_PAGE_STAGING .. +HAL_SLOT_PAGES-1 the staging slot: where an update arrives
 *   HAL_PAGE_BOOTREC                      the boot record: starts not yet confirmed (boot.h)
 * (STM32F103x8, 64 KiB: bootloader 7 KiB at 0x08000000 and the boot record in the last
 * KiB of its 8 KiB region, 0x08001C00; application 26 KiB at 0x08002000, staging 26 KiB
 * at 0x08008800, store 4 KiB at 0x0800F000.)
 * Erased flash reads 0xFF; programming only clears bits, one aligned half-word at a time.
 * Program and erase may stall the CPU (tens of ms for an erase); main loop only.
 * Both return false if the operation failed (the store then treats the page as bad). */
#define HAL_FLASH_PAGE_BYTES 1024u
#define HAL_FLASH_PAGES 4u
#define HAL_SLOT_PAGES 26u
#define HAL_PAGE_APP HAL_FLASH_PAGES
#define HAL_PAGE_STAGING (HAL_PAGE_APP + HAL_SLOT_PAGES)
#define HAL_PAGES_ALL (HAL_PAGE_STAGING + HAL_SLOT_PAGES) /* store and both slots */
#define HAL_PAGE_BOOTREC HAL_PAGES_ALL /* numbered after them, one page */

/* Memory-mapped, read-only view of page p. Any context. */
const uint8_t *hal_flash_page(struct hal *h, uint8_t p);

/* Erase page p (every byte 0xFF). */
bool hal_flash_erase(struct hal *h, uint8_t p);

/* Program the half-word at byte offset off (even) of page p; the half-word was erased. */
bool hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value);

/* The MCU's unique identity, 12 bytes (issue 27, include/ident.h): the STM32F1's 96-bit
 * unique ID at 0x1FFFF7E8; under QEMU, whose STM32F100 has none, 12 bytes at the top of
 * its flash, 0x0801FFF0, that the test loads per instance; on the host, each node's own
 * (servo-sim --servo ID:VARIANT:UID). Never changes while the MCU runs. Any context. */
#define HAL_UID_BYTES 12u
const uint8_t *hal_uid(struct hal *h);

/* Reset the MCU (the bootloader runs again and starts the installed image). Main loop,
 * after the last answer has left the wire. Does not return on an MCU; the host port
 * records the request and its harness power-cycles the servo. */
void hal_restart(struct hal *h);

/* Motor, sensors and board outputs. Called from the control tick, which runs in the main
 * loop (servo_poll), never from an interrupt.
 * Drive: signed duty in per mille of the supply, +HAL_DUTY_MAX turns the output shaft
 * in the positive direction of PROTOCOL.md §5.4; 0 lets the motor coast. */
#define HAL_DUTY_MAX 1000

/* Gate driver on (true) or off (torque off, lowest power: sleep and unload). */
void hal_motor_enable(struct hal *h, bool on);

/* H-bridge PWM duty, -HAL_DUTY_MAX..HAL_DUTY_MAX. */
void hal_motor_drive(struct hal *h, int16_t duty);

/* Output shaft position in board counts (struct board counts_per_rev per turn), counting
 * up in the positive direction; a free-running 32-bit count that wraps. */
int32_t hal_motor_position(struct hal *h);

/* Motor current in mA (magnitude), supply voltage in mV, board temperature in 0.1 C. */
uint16_t hal_motor_current_ma(struct hal *h);
uint16_t hal_supply_mv(struct hal *h);
int16_t hal_temperature_dc(struct hal *h);

/* Photo switches, raw: bit 0 switch 1, bit 1 switch 2 (1 = light path interrupted). */
uint8_t hal_photo_switches(struct hal *h);

/* The 120 ohm RS485 terminator (register 20). */
void hal_rs485_termination(struct hal *h, bool on);

/* Fittings as capability bits (grblHAL's hal.h model): the port reports those it has,
 * each board states those it needs (struct board's fittings, board.h), and motion_init()
 * checks that the board's are among the port's. A port that lacks one (a missing switch
 * or terminator, the other kind of position sensor) gets a servo that answers but never
 * moves: safety_unfit(). */
#define HAL_CAP_PHOTO 0x01u      /* the two homing photo switches */
#define HAL_CAP_TERMINATOR 0x02u /* the switchable 120 ohm RS485 terminator (register 20) */
#define HAL_CAP_ENCODER 0x04u    /* position from a quadrature encoder */
#define HAL_CAP_POT 0x08u        /* position from an output-shaft potentiometer */
uint8_t hal_capabilities(struct hal *h);

/* Independent watchdog: start once at boot (it cannot be stopped), feed regularly. */
void hal_watchdog_start(struct hal *h);

/* Did the previous run end by losing power (power-on, brown-out or the reset pin), rather
 * than by the watchdog or a fault / hal_restart()? Reads and clears the MCU's reset flags,
 * so the bootloader asks once per boot (boot_start). */
bool hal_reset_by_power(struct hal *h);
void hal_watchdog_feed(struct hal *h);

#endif
