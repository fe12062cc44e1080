/* hal_template.c - the porting checklist: every function of hal/hal.h, stubbed, with the
 * context the core calls it from and what a port must guarantee. Copy this file to
 * hal/<chip>/, fill in each function, and compare with hal/stm32f1/ (a complete port)
 * and hal/host/ (the simulation the tests run on). The stm32 build compiles it (never
 * links it), so its signatures follow hal.h.
 *
 * The whole port in one picture:
 *   - Interrupt context: the UART receive interrupt calls servo_rx_isr(servo, byte) once
 *     per byte, in order, and nothing else of the core. A time base interrupt (if the
 *     clock needs one) only counts. Everything else runs in the main loop:
 *         servo_init(&servo, &board_x, &hal);  then  for (;;) servo_poll(&servo);
 *   - servo_init() starts the watchdog; servo_poll() feeds it. A port's main() adds
 *     nothing to the loop except, at most, sleeping when it can prove nothing is due.
 *   - Whatever the receive interrupt runs (its handler, servo_rx_isr, frame_rx_byte,
 *     hal_clock_us) must keep running while the flash is being erased or programmed:
 *     on parts whose CPU stalls on flash reads meanwhile, put that code, the vector
 *     table and the flash wait loop in RAM (hal/stm32f1/README.md shows how).
 *   - No floating point, no heap; every wait on hardware is bounded by a time-out, so
 *     a missing peripheral (or an emulator without it) never hangs the boot.
 *   - Firmware update (PROTOCOL.md §10): the application is linked for the application
 *     slot; a bootloader at the reset address calls boot_start() (boot.h) before
 *     anything else: it installs a staged update (boot_install()) and records the start
 *     in the boot record, then the bootloader starts the application with the watchdog
 *     running, or (false) runs the loader (loader.h) in the same way as main() runs the
 *     servo (hal/stm32f1/boot_main.c). Calling boot_install() alone records no start, so
 *     an image that never confirms (boot_confirm(), servo_poll() does it) would be
 *     started again for ever instead of falling back to update mode. The port maps
 *     HAL_PAGE_BOOTREC for the boot record. */
#include "hal.h"

struct hal {
    int unused; /* the port's state: one static instance on a single-chip port */
};

/* Any context (main loop and the receive interrupt). Microseconds since boot, wrapping
 * at 2^32, monotonic: a later call never returns an earlier time, also across the
 * interrupt boundary (a tick interrupt that is pending but not yet serviced must be
 * counted). Resolution 1 us or better; it times the 2 ms inter-byte gap, the return
 * delay (500 us steps) and the 1 ms control tick. */
uint32_t hal_clock_us(struct hal *h)
{
    (void)h;
    return 0;
}

/* Main loop, never while a transmission is in progress (the core sets a new baud only
 * after the last stop bit of the answer that carried the change). Takes effect for the
 * next byte in both directions; 2400 to 1792000 baud (PROTOCOL.md §5.2), 8N1. */
void hal_uart_set_baud(struct hal *h, uint32_t baud)
{
    (void)h;
    (void)baud;
}

/* Main loop. The bit rate hal_uart_set_baud(h, baud) would really make on the clock in
 * force (the divider's rounding; what a fall-back clock cannot reach at all). The core
 * refuses a baud code that this misses by more than 2 %. A UART that makes every rate of
 * PROTOCOL.md §5.2 exactly returns baud. */
uint32_t hal_uart_baud_achieved(const struct hal *h, uint32_t baud)
{
    (void)h;
    return baud;
}

/* Main loop, never while hal_uart_tx_busy() is true. Returns at once: the bytes go out
 * from interrupts (or DMA). Asserts the RS485 driver enable before the first start bit.
 * buf stays valid and untouched until hal_uart_tx_busy() is false. While sending, the
 * receiver must not hand the echo of our own bytes to servo_rx_isr(). */
void hal_uart_send(struct hal *h, const uint8_t *buf, uint16_t len)
{
    (void)h;
    (void)buf;
    (void)len;
}

/* Main loop. True until the last stop bit of the last byte has left the shift register
 * (transmission complete, not merely "data register empty") AND the driver enable has
 * been released; the core latches a new ID or baud right after it turns false. */
bool hal_uart_tx_busy(struct hal *h)
{
    (void)h;
    return false;
}

/* Main loop. Mask the interrupts that call into the core (at least the UART receive
 * interrupt) and return the previous state; hal_irq_restore() puts it back. Must nest.
 * Keep the time base running if hal_clock_us() needs its interrupt. */
uint32_t hal_irq_save(struct hal *h)
{
    (void)h;
    return 0;
}

void hal_irq_restore(struct hal *h, uint32_t state)
{
    (void)h;
    (void)state;
}

/* Any context. A memory-mapped, read-only view of page p, HAL_FLASH_PAGE_BYTES long, in
 * the core's numbering (hal.h): pages 0 .. HAL_FLASH_PAGES-1 are the store, then the
 * application slot (HAL_PAGE_APP, HAL_SLOT_PAGES pages: the image that runs, linked
 * there), the staging slot (HAL_PAGE_STAGING: where an update arrives) and the boot
 * record (HAL_PAGE_BOOTREC, boot.h: the bootloader's START and the application's
 * CONFIRM marks). The store's pages are reserved (the linker script keeps every image
 * out of them) and survive a firmware update. A page number outside these: return 0; a
 * port without a bootloader may return 0 for HAL_PAGE_BOOTREC too (the application then
 * confirms nothing). With a bootloader (hal.h's flash map on the STM32F103: bootloader
 * 7 KiB and the boot record's page, the two slots, the store), the bootloader's own code
 * is never among the pages. */
const uint8_t *hal_flash_page(struct hal *h, uint8_t p)
{
    (void)h;
    (void)p;
    return 0;
}

/* Main loop. Erase page p to all 0xFF; may stall the main loop for tens of ms, but the
 * receive interrupt must keep running (see above). False if the hardware reports a
 * failure (the store then verifies and treats the page as bad) or p is not a page of
 * hal_flash_page(). The application should refuse its own slot (it runs from there):
 * only the bootloader installs into it. */
bool hal_flash_erase(struct hal *h, uint8_t p)
{
    (void)h;
    (void)p;
    return false;
}

/* Main loop. Program the erased half-word at even byte offset off of page p; false if
 * the hardware reports a failure or the read-back differs. */
bool hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value)
{
    (void)h;
    (void)p;
    (void)off;
    (void)value;
    return false;
}

/* Main loop (control tick). Gate driver on, or off: torque off, lowest power. Off must
 * also stop the PWM drive. At reset, before the core runs, the bridge must already be
 * off (pins in a safe state, pull-downs on the board). */
void hal_motor_enable(struct hal *h, bool on)
{
    (void)h;
    (void)on;
}

/* Main loop (control tick). Signed duty -HAL_DUTY_MAX..HAL_DUTY_MAX; positive turns the
 * output shaft in the positive direction of PROTOCOL.md §5.4 (the board's wiring flips
 * it if needed); 0 coasts. Clamp anything outside the range. Never blocks. */
void hal_motor_drive(struct hal *h, int16_t duty)
{
    (void)h;
    (void)duty;
}

/* Main loop (control tick, every 1 ms). Output shaft position in board counts (struct
 * board counts_per_rev per turn), counting up in the positive direction; a free-running
 * 32-bit count that wraps. A 16-bit hardware counter is extended in software: correct
 * as long as it moves less than half its range between two calls. */
int32_t hal_motor_position(struct hal *h)
{
    (void)h;
    return 0;
}

/* Main loop (control tick). Sensors, never blocking (sample in the background, e.g. ADC
 * scan + DMA, and return the latest value): motor current magnitude in mA, supply in
 * mV, board temperature in 0.1 C. The safety layer compares them with the limits in
 * struct board and the control table. */
uint16_t hal_motor_current_ma(struct hal *h)
{
    (void)h;
    return 0;
}

uint16_t hal_supply_mv(struct hal *h)
{
    (void)h;
    return 0;
}

int16_t hal_temperature_dc(struct hal *h)
{
    (void)h;
    return 0;
}

/* Main loop. Homing photo switches, raw: bit 0 switch 1, bit 1 switch 2, 1 = light path
 * interrupted. 0 on boards without switches. */
uint8_t hal_photo_switches(struct hal *h)
{
    (void)h;
    return 0;
}

/* Power-up. The fittings this hardware has (HAL_CAP_*, hal.h): the board's must be
 * among them, or the servo never moves. */
uint8_t hal_capabilities(struct hal *h)
{
    (void)h;
    return HAL_CAP_PHOTO | HAL_CAP_TERMINATOR | HAL_CAP_ENCODER;
}

/* Main loop. Switch the 120 ohm RS485 terminator (register 20); a no-op without one. */
void hal_rs485_termination(struct hal *h, bool on)
{
    (void)h;
    (void)on;
}

/* Main loop. Start the independent watchdog once (from servo_init); it cannot be
 * stopped. Its period must outlast the longest main-loop stall (a flash erase) and be
 * short enough that a hung loop stops the motor quickly (hundreds of ms). */
void hal_watchdog_start(struct hal *h)
{
    (void)h;
}

/* Main loop. Reload the watchdog (servo_poll calls it only while the control tick runs). */
void hal_watchdog_feed(struct hal *h)
{
    (void)h;
}

/* Main loop, after the answer that announced it has left the wire (hal_uart_tx_busy()
 * false). Reset the MCU as a power-up would, so the bootloader runs and installs the
 * update just staged (boot.h): outputs safe first, then the core's system reset (on a
 * Cortex-M: cpsid i; dsb; SCB->AIRCR = 0x05FA0000 | SYSRESETREQ; dsb; loop). Does not
 * return on an MCU; the host port only records the request. */
void hal_restart(struct hal *h)
{
    (void)h;
}

/* Any context. The MCU's unique identity, 12 bytes that never change (a factory-programmed
 * unique ID; an MCU without one: a serial number written once at production). */
const uint8_t *hal_uid(struct hal *h)
{
    static const uint8_t uid[HAL_UID_BYTES]; /* TODO(port): the MCU's unique ID */
    (void)h;
    return uid;
}

bool hal_reset_by_power(struct hal *h)
{
    (void)h;
    return true; /* TODO(port): read and clear the MCU's reset-cause flags */
}
