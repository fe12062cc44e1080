/* boot_main.c - the bootloader (board/stm32f103x8-boot.ld: 7 KiB at the reset address,
 * then the boot record's page).
 *
 * At reset, before anything else, gpio_init() drives the RS485 driver enable and the
 * bridge's nSLEEP low: until then they float (the board's pull-downs hold them,
 * ref_pcb.h), and an install lasts about 2 s, during which a floating driver enable
 * could hold the shared bus. Then, on the reset clock (HSI 8 MHz), boot_start()
 * (boot.h) installs a verified update waiting in the staging slot and says whether to
 * start the application: its slot holds a valid image for this board's model, and fewer
 * than BOOT_STARTS_MAX of its starts went unconfirmed (it hung or crashed before it
 * answered on the bus or ran 2 s); it has then recorded this start. The application
 * starts as if from reset: nothing has been set up that it would have to undo, except
 * the watchdog and the output pins, which its own gpio_init() sets again the same way.
 * If not, the bootloader stays in update mode: the loader (loader.h) answers the §10
 * update frames at the stored ID and baud, and restarts once an update has been
 * staged; the next boot installs it. The motor is never driven here: the bridge stays
 * asleep and motor.c is not even linked.
 *
 * Watchdog: after any reset the IWDG is stopped (unless the option bytes select the
 * hardware watchdog: every FPEC wait feeds it, flash.c). The install runs without it: a
 * page erase and copy take ~2 s for a full slot, and a reset in the middle only means
 * copying again. It is started (~250 ms, as the application sets it) just before the
 * jump, so an application that hangs before its own start-up reaches servo_init() is
 * reset too, and the next boot counts that start. Update mode starts it at the same point (its set-up takes
 * ~25 ms at most, the clock's fall-backs) and feeds it every loop pass: a hung loader
 * resets into the bootloader, which comes back to update mode. The longest stall of a
 * pass is one block's erase and programming (< 100 ms). */
#include "boot.h"
#include "hal_stm32f1.h"
#include "loader.h"
#include "servo.h"

#ifndef SERVO_BOARD
#error "SERVO_BOARD (board_arm, board_base, ...) comes from CMake's BOARD"
#endif
#ifndef SERVO_MODEL
#error "SERVO_MODEL (BOARD_MODEL_ARM, ...) comes from CMake's BOARD"
#endif

struct hal hal_stm32;
static struct servo servo; /* the loader's state: table, receiver, store, update */

extern const uint32_t _app_start[]; /* stm32f103x8-memory.ld: the application's vectors */

/* Start the application as the core would from reset: its vector table, its stack, its
 * reset handler (which copies its vectors to RAM and moves VTOR there). Interrupts were
 * never enabled, SysTick never started. */
static __attribute__((noreturn)) void start_application(void)
{
    REG_WRITE(SCB->vtor, (uint32_t)(uintptr_t)_app_start);
    CPU_DSB();
    CPU_ISB();
    CPU_JUMP(_app_start[0], _app_start[1]); /* the new stack pointer, then the branch */
    __builtin_unreachable();
}

int main(void)
{
    struct hal *h = &hal_stm32;
    gpio_init(); /* first: the RS485 driver and the bridge off, not floating (above) */
    bool start = boot_start(h, SERVO_MODEL);
    hal_watchdog_start(h); /* an application that hangs before it feeds it is reset */
    if (start)
        start_application();

    clock_init(h);
    clock_tick_start(h); /* hal_clock_us() */
    uart_init(h);        /* receiver on, interrupt still off */
    loader_init(&servo, &SERVO_BOARD, h); /* stored ID and baud */
    uart_start(h, &servo); /* from here bytes reach the frame receiver */
    bool emulated = h->clock_source == CLOCK_NO_RCC;
    for (;;) {
        servo_poll(&servo); /* feeds the watchdog; restarts once an update is staged */
        if (emulated) /* as in main.c: let QEMU's I/O thread deliver the bytes */
            CPU_WFI();
    }
}
