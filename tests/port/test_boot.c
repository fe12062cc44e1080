/* test_boot.c - the bootloader itself (hal/stm32f1/boot_main.c and the port and core it
 * links, all built with SERVO_BOOTLOADER as stm32.cmake builds them) from reset on the
 * register models: it drives the RS485 driver enable and the bridge's nSLEEP low before
 * it does anything else, so a booting servo never holds the shared bus; it installs a
 * staged image through the FPEC, records the start, starts the watchdog and branches to
 * the application; without a valid application it answers the §10 handshake. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "boot.h"
#include "hal_stm32f1.h"
#include "model.h"
#include "port_wire.h"
#include "regs.h"
#include "store.h"

int boot_main(void); /* boot_main.c's main(), renamed for the test */

#define APP0 0x08002000u
#define STAGING0 0x08008800u
#define BOOTREC 0x08001C00u
#define STAGING0 0x08008800u
#define IMAGE_BYTES 3000u

static jmp_buf stopped;
static uint8_t img[IMAGE_BYTES];

static void no_violation(void)
{
    if (model.violations)
        fail_msg("%u violation(s), the first: %s", model.violations, model.violation);
}

/* A programmer wrote img into the slot at addr (no FPEC involved). */
static void program_directly(uint32_t addr, const uint8_t *data, uint32_t n)
{
    memcpy(model.fpec.mem + (addr - MODEL_FLASH_BASE), data, n);
}

static void board_with_application(void)
{
    model_init();
    model.usart.de_pin = BOARD_PIN_RS485_DE;
    port_image_build(img, IMAGE_BYTES, BOARD_MODEL_ARM, 7, 1);
    program_directly(APP0, img, IMAGE_BYTES);
}

/* Reset: run the bootloader until it branches away or the test's deadline. */
static int run_bootloader(uint64_t for_ticks)
{
    model.deadline = for_ticks ? model.now + for_ticks : 0;
    int why = model_catch(stopped);
    if (why == 0)
        boot_main();
    return why;
}

/* ---- Bus and bridge safe from the first instant ------------------------------------ */

static uint32_t first_other_access;
static enum model_pin de_then, sleep_then;

/* At the first access to anything but the clock enables and the GPIO ports, where are
 * the driver enable and nSLEEP? */
static void spy(uintptr_t addr, bool write)
{
    (void)write;
    bool rcc = addr >= 0x40021000u && addr < 0x40021400u;
    bool gpio = addr >= 0x40010800u && addr < 0x40011400u;
    if (first_other_access || rcc || gpio)
        return;
    first_other_access = model.accesses;
    de_then = model_pin_state(BOARD_PIN_RS485_DE);
    sleep_then = model_pin_state(BOARD_PIN_DRIVER_EN);
}

static void driver_enable_and_nsleep_are_low_before_anything_else(void **state)
{
    (void)state;
    board_with_application();
    /* The whole install of a staged image (about 2 s for a full slot) happens here, so
     * the pins must be driven from the very start. */
    port_image_build(img, IMAGE_BYTES, BOARD_MODEL_ARM, 8, 2);
    program_directly(STAGING0, img, IMAGE_BYTES);
    uint8_t mark[2] = {0, 0};
    program_directly(STAGING0 + 25u * 1024u + IMAGE_MARK_OFFSET, mark, 2);
    assert_int_equal(model_pin_state(BOARD_PIN_RS485_DE), MODEL_PIN_FLOATING); /* reset */
    first_other_access = 0;
    model.on_access = spy;
    assert_int_equal(run_bootloader(0), MODEL_EXIT_JUMP);
    model.on_access = NULL;
    assert_true(first_other_access != 0);
    assert_int_equal(de_then, MODEL_PIN_LOW);
    assert_int_equal(sleep_then, MODEL_PIN_LOW);
    assert_true(first_other_access <= 32u); /* a handful of GPIO writes, then the rest */
    /* ...and they stay so all through the install and the jump. */
    assert_int_equal(model_pin_state(BOARD_PIN_RS485_DE), MODEL_PIN_LOW);
    assert_int_equal(model_pin_state(BOARD_PIN_DRIVER_EN), MODEL_PIN_LOW);
    assert_int_equal(memcmp(model_flash(APP0), img, IMAGE_BYTES), 0); /* installed */
    assert_int_equal(model.usart.tx_len, 0);
    no_violation();
}

/* ---- Starting the application ------------------------------------------------------ */

static void starts_the_application_with_the_watchdog_running(void **state)
{
    (void)state;
    board_with_application();
    assert_int_equal(run_bootloader(0), MODEL_EXIT_JUMP);
    /* As the core would from reset: its stack pointer, its reset vector, its table. */
    assert_int_equal(model.jump_sp, 0x20001800u);
    assert_int_equal(model.jump_pc, ((const uint32_t *)model_flash(APP0))[1]);
    assert_int_equal(model.cpu.vtor, APP0);
    assert_true(model.iwdg.on);
    assert_int_equal(model.iwdg.pr, 3); /* LSI / 32 */
    assert_int_equal(model.iwdg.rlr, 312);
    /* One START mark (0xFF00) written through the FPEC, which is locked again. */
    assert_int_equal(model_flash(BOOTREC)[0], 0x00);
    assert_int_equal(model_flash(BOOTREC)[1], 0xFF);
    assert_int_equal(model_flash(BOOTREC)[2], 0xFF);
    assert_true(model.fpec.cr & FLASH_CR_LOCK);
    assert_int_equal(model.rcc.cfgr & 0xCu, 0u); /* still on the reset clock (HSI) */
    no_violation();
}

/* The application hangs: the watchdog the bootloader started resets the chip ~250 ms
 * after the jump; three such starts, and the bootloader stays in update mode. */
static void three_unconfirmed_starts_keep_it_in_update_mode(void **state)
{
    (void)state;
    board_with_application();
    for (int start = 0; start < 3; start++) {
        assert_int_equal(run_bootloader(0), MODEL_EXIT_JUMP);
        uint64_t t0 = model.now;
        if (model_catch(stopped) == 0)
            for (;;)
                model_run(MODEL_MS(1)); /* the application hangs, feeding nothing */
        assert_true(model.now - t0 >= MODEL_MS(240) && model.now - t0 <= MODEL_MS(260));
        assert_true(model.rcc.csr & (1u << 29)); /* IWDGRSTF */
    }
    /* Update mode: it listens, at the stored baud (the arm's default, 9600). */
    assert_int_equal(run_bootloader(MODEL_MS(30)), MODEL_EXIT_DEADLINE);
    assert_int_equal(model_usart_bps(), 72000000u / 7500u);
    assert_int_equal(model_pin_state(BOARD_PIN_RS485_DE), MODEL_PIN_LOW);
    no_violation();
}

/* The host sends the §10 handshake to ID 1 at 9600 baud, 30 ms from now (after reset);
 * the end of its last stop bit. */
static uint64_t send_handshake_after_30_ms(void)
{
    uint8_t hs[8];
    uint16_t n = enter_frame(hs, 1);
    model.usart.wire_free = model.now + MODEL_MS(30);
    model_wire_send(hs, n, 9600);
    return model.usart.wire_free;
}

/* ---- Update mode ------------------------------------------------------------------- */

static void without_an_application_it_answers_the_update_handshake(void **state)
{
    (void)state;
    model_init();
    model.usart.de_pin = BOARD_PIN_RS485_DE;
    /* The host sends the handshake 30 ms after reset, at the stored baud. */
    uint64_t sent = send_handshake_after_30_ms();
    assert_int_equal(run_bootloader(MODEL_MS(80)), MODEL_EXIT_DEADLINE);
    assert_int_equal(model.rcc.cfgr & 0xCu, 0x8u); /* on the PLL: 72 MHz */
    assert_true(model.iwdg.on && model.iwdg.feeds > 100u);
    static const uint8_t want[] = {0xD5, 0x5D, 0x01, 0x03, 0x00, 0x43, 0x47};
    assert_int_equal(model.usart.tx_len, sizeof want);
    for (uint32_t i = 0; i < sizeof want; i++) {
        assert_int_equal(model.usart.tx[i].byte, want[i]);
        assert_true(model.usart.tx[i].de_all_along);
    }
    /* After the return delay (the arm's 16 x 500 us), counted from the end of the last
     * byte's stop bit, as the application counts it (uart.c). Then back to back. */
    uint64_t after = model.usart.tx[0].start - sent;
    assert_true(after >= MODEL_US(7999) && after <= MODEL_US(8030)); /* 1 us ticks */
    assert_int_equal(model.usart.tx[6].start - model.usart.tx[0].start,
                     6u * 10u * (MODEL_HZ / 9600u));
    /* The driver enable: released after the last stop bit, promptly. */
    assert_int_equal(model_pin_state(BOARD_PIN_RS485_DE), MODEL_PIN_LOW);
    no_violation();
}

/* Return delay 0 stored (register 5: a host wanting the fastest answers): update mode
 * answers as soon as it may, but never while the host's last stop bit is on the wire,
 * where the two drivers would fight over the bus (RXNE comes half a bit, 52 us at 9600,
 * before the stop bit ends). */
static void with_return_delay_0_update_mode_never_answers_over_the_stop_bit(void **state)
{
    (void)state;
    static struct regs r;
    static struct store st;
    model_init();
    model.usart.de_pin = BOARD_PIN_RS485_DE;
    model.gpio.watch = BOARD_PIN_RS485_DE;
    memset(&hal_stm32, 0, sizeof hal_stm32);
    regs_init(&r, &board_arm);
    store_load(&st, &hal_stm32, &r, 0);
    regs_set(&r, REG_RETURN_DELAY, 0);
    (void)regs_take_ee_changed(&r);
    store_sync(&st, &r, 0);
    model_reset(MODEL_RESET_POWER);
    uint64_t sent = send_handshake_after_30_ms();
    assert_int_equal(run_bootloader(MODEL_MS(80)), MODEL_EXIT_DEADLINE);
    assert_int_equal(model.usart.tx_len, 7);
    assert_int_equal(model.usart.tx[4].byte, 0x00); /* ERR 0 */
    uint64_t up = MODEL_NEVER;
    for (uint32_t i = 0; i < model.gpio.edges && up == MODEL_NEVER; i++)
        if (model.gpio.edge[i].at >= sent - MODEL_MS(1) &&
            model.gpio.edge[i].state == MODEL_PIN_HIGH)
            up = model.gpio.edge[i].at;
    /* Within the clock's resolution (1 us) of the stop bit's end, on either side. */
    if (up + MODEL_US(1) < sent)
        fail_msg("driver enable up %llu us before the host's stop bit ended",
                 (unsigned long long)((sent - up) / MODEL_US(1)));
    assert_true(model.usart.tx[0].start + MODEL_US(1) >= sent);
    assert_true(model.usart.tx[0].start <= sent + MODEL_US(10)); /* but at once */
    no_violation();
}

/* ---- An install the FPEC refuses ---------------------------------------------------- */

/* The application slot's second 4 KiB is write-protected (WRPRTERR at its first page):
 * the install stops half-way, the slot holds neither image, and the bootloader stays in
 * update mode, the driver enable low, the staged copy kept. With the protection gone,
 * the next boot installs it and starts it. */
static void a_write_protected_install_leaves_update_mode_then_completes(void **state)
{
    (void)state;
    static uint8_t staged[5000];
    board_with_application();
    port_image_build(staged, sizeof staged, BOARD_MODEL_ARM, 8, 2);
    program_directly(STAGING0, staged, sizeof staged);
    model.fpec.mem[STAGING0 - MODEL_FLASH_BASE + 25u * 1024u + IMAGE_MARK_OFFSET] = 0;
    model.fpec.mem[STAGING0 - MODEL_FLASH_BASE + 25u * 1024u + IMAGE_MARK_OFFSET + 1u] = 0;
    model.fpec.wrpr = ~(1u << 3); /* 0x08003000-0x08003FFF */
    assert_int_equal(run_bootloader(MODEL_MS(200)), MODEL_EXIT_DEADLINE);
    /* The first 4 KiB copied, the next page refused: the slot is neither image. */
    assert_int_equal(memcmp(model_flash(APP0), staged, 4096), 0);
    uint32_t rest = sizeof staged - 4096u;
    assert_true(memcmp(model_flash(APP0 + 4096u), &staged[4096], rest) != 0);
    assert_true(model.fpec.sr & FLASH_SR_WRPRTERR);
    assert_int_equal(model_pin_state(BOARD_PIN_RS485_DE), MODEL_PIN_LOW);
    assert_int_equal(model_pin_state(BOARD_PIN_DRIVER_EN), MODEL_PIN_LOW);
    assert_int_equal(memcmp(model_flash(STAGING0), staged, sizeof staged), 0);
    assert_true(model.fpec.cr & FLASH_CR_LOCK);
    no_violation();
    model.fpec.wrpr = 0xFFFFFFFFu;
    model_reset(MODEL_RESET_POWER);
    assert_int_equal(run_bootloader(0), MODEL_EXIT_JUMP);
    assert_int_equal(memcmp(model_flash(APP0), staged, sizeof staged), 0);
    no_violation();
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(driver_enable_and_nsleep_are_low_before_anything_else),
        cmocka_unit_test(starts_the_application_with_the_watchdog_running),
        cmocka_unit_test(three_unconfirmed_starts_keep_it_in_update_mode),
        cmocka_unit_test(without_an_application_it_answers_the_update_handshake),
        cmocka_unit_test(a_write_protected_install_leaves_update_mode_then_completes),
        cmocka_unit_test(with_return_delay_0_update_mode_never_answers_over_the_stop_bit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
