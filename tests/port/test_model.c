/* test_model.c - the register models themselves against RM0008, register by register,
 * with no driver in between: the port's tests are worth what the models are, so each
 * rule a driver test relies on (a wrong key locks the FPEC, SR then DR clears ORE, a
 * PR write needs the key...) is checked here on its own. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "model.h"

#define FLASH_KEYR 0x40022004u
#define FLASH_SR 0x4002200Cu
#define FLASH_CR 0x40022010u
#define FLASH_AR 0x40022014u
#define RCC_APB2ENR 0x40021018u
#define USART_SR 0x40013800u
#define USART_DR 0x40013804u
#define USART_BRR 0x40013808u
#define USART_CR1 0x4001380Cu
#define IWDG_KR 0x40003000u
#define IWDG_PR 0x40003004u
#define IWDG_RLR 0x40003008u
#define IWDG_SR 0x4000300Cu
#define GPIOA_CRH 0x40010804u
#define GPIOA_ODR 0x4001080Cu
#define GPIOA_BSRR 0x40010810u

static jmp_buf stopped;

static uint32_t rd(uint32_t addr)
{
    return model_read(addr, 4);
}

static void wr(uint32_t addr, uint32_t v)
{
    model_write(addr, v, 4);
}

static void unlock(void)
{
    wr(FLASH_KEYR, 0x45670123u);
    wr(FLASH_KEYR, 0xCDEF89ABu);
}

/* ---- FPEC -------------------------------------------------------------------------- */

/* KEY1 then KEY2 unlocks FLASH_CR; a wrong key (or any key while unlocked) locks it until
 * the next reset. */
static void fpec_keys(void **state)
{
    (void)state;
    model_init();
    assert_true(rd(FLASH_CR) & 0x80u);
    unlock();
    assert_false(rd(FLASH_CR) & 0x80u);
    wr(FLASH_CR, 0x80u); /* LOCK again */
    wr(FLASH_KEYR, 0x45670123u);
    wr(FLASH_KEYR, 0x12345678u); /* wrong */
    assert_int_equal(model.violations, 1);
    unlock();
    assert_true(rd(FLASH_CR) & 0x80u); /* still locked: until reset */
    model_reset(MODEL_RESET_SOFT);
    unlock();
    assert_false(rd(FLASH_CR) & 0x80u);
    uint32_t v = model.violations;
    unlock(); /* a key while unlocked */
    assert_true(model.violations > v);
    assert_true(rd(FLASH_CR) & 0x80u);
}

/* PG: a half-word write programs after BSY (program time), EOP; a non-erased half-word
 * gives PGERR unless 0x0000 is written; a byte or word write is a bus error. */
static void fpec_program(void **state)
{
    (void)state;
    model_init();
    unlock();
    wr(FLASH_CR, 1u); /* PG */
    uint64_t t0 = model.now;
    model_write(0x08001000u, 0x1234u, 2);
    assert_true(rd(FLASH_SR) & 1u); /* BSY */
    while (rd(FLASH_SR) & 1u) {
    }
    assert_true(model.now - t0 >= model.fpec.program_ticks);
    assert_int_equal(rd(FLASH_SR) & 0x35u, 0x20u); /* EOP only */
    assert_int_equal(model_flash(0x08001000u)[0], 0x34);
    wr(FLASH_SR, 0x20u); /* EOP: write 1 to clear */
    assert_int_equal(rd(FLASH_SR) & 0x20u, 0u);
    model_write(0x08001000u, 0x1000u, 2); /* over a written one: skipped */
    assert_int_equal(rd(FLASH_SR) & 0x04u, 0x04u); /* PGERR */
    assert_int_equal(model_flash(0x08001000u)[1], 0x12);
    wr(FLASH_SR, 0x04u);
    model_write(0x08001000u, 0x0000u, 2); /* 0x0000 over anything: programmed */
    while (rd(FLASH_SR) & 1u) {
    }
    assert_int_equal(rd(FLASH_SR) & 0x04u, 0u);
    assert_int_equal(model_flash(0x08001000u)[1], 0x00);
    assert_int_equal(model.violations, 0);
    model_write(0x08001004u, 0x12345678u, 4); /* word write */
    assert_int_equal(model.violations, 1);
    wr(FLASH_CR, 0u);
    model_write(0x08001006u, 0x1111u, 2); /* without PG */
    assert_int_equal(model.violations, 2);
}

/* PER + AR + STRT erases the page holding AR, of the part's page size; WRPR protects
 * 4 KiB a bit (WRPRTERR, nothing erased); FLASH_CR and AR are not to be written while
 * BSY. */
static void fpec_erase(void **state)
{
    (void)state;
    model_init();
    memset(model.fpec.mem, 0, 8192);
    unlock();
    wr(FLASH_CR, 2u);
    wr(FLASH_AR, 0x08000C10u);
    wr(FLASH_CR, 2u | 0x40u);
    wr(FLASH_AR, 0x08000000u); /* while BSY: ignored, a violation */
    assert_int_equal(model.violations, 1);
    while (rd(FLASH_SR) & 1u) {
    }
    assert_int_equal(model_flash(0x08000C00u)[0], 0xFF);
    assert_int_equal(model_flash(0x08000FFFu)[0], 0xFF);
    assert_int_equal(model_flash(0x08000BFFu)[0], 0x00); /* the neighbours kept */
    assert_int_equal(model_flash(0x08001000u)[0], 0x00);
    /* 2 KiB pages: the neighbour goes too. */
    model.fpec.page_bytes = 2048;
    wr(FLASH_CR, 2u);
    wr(FLASH_AR, 0x08001400u);
    wr(FLASH_CR, 2u | 0x40u);
    while (rd(FLASH_SR) & 1u) {
    }
    assert_int_equal(model_flash(0x08001000u)[0], 0xFF);
    /* Protected: WRPRTERR at once, nothing erased. */
    model.fpec.wrpr = ~(1u << 0); /* 0x08000000-0x08000FFF */
    wr(FLASH_SR, 0x35u);
    wr(FLASH_CR, 2u);
    wr(FLASH_AR, 0x08000400u);
    wr(FLASH_CR, 2u | 0x40u);
    assert_int_equal(rd(FLASH_SR) & 0x11u, 0x10u);
    assert_int_equal(model_flash(0x08000400u)[0], 0x00);
    /* A write of CR while BSY is what the port must never do. */
    model.fpec.wrpr = 0xFFFFFFFFu;
    wr(FLASH_CR, 2u);
    wr(FLASH_AR, 0x08000400u);
    wr(FLASH_CR, 2u | 0x40u);
    model.violations = 0;
    wr(FLASH_CR, 0x80u);
    assert_int_equal(model.violations, 1);
    assert_non_null(strstr(model.violation, "relocked"));
}

/* A power cut at the chosen operation stops the code; torn, a program leaves some of
 * its bits, an erase sets some. */
static void fpec_power_cut(void **state)
{
    (void)state;
    model_init();
    unlock();
    wr(FLASH_CR, 1u);
    model.fpec.cut_at = 2;
    model.fpec.cut_kind = MODEL_CUT_TORN;
    int why = model_catch(stopped);
    if (why == 0) {
        model_write(0x08002000u, 0x0F0Fu, 2);
        while (rd(FLASH_SR) & 1u) {
        }
        model_write(0x08002002u, 0x0000u, 2);
        for (;;)
            (void)rd(FLASH_SR);
    }
    assert_int_equal(why, MODEL_EXIT_POWER_CUT);
    assert_int_equal(model_flash(0x08002000u)[0], 0x0F);
    uint16_t torn = (uint16_t)(model_flash(0x08002002u)[0] | (model_flash(0x08002002u)[1] << 8));
    assert_true(torn != 0x0000u); /* some of the bits to clear stayed set */
}

/* ---- USART ------------------------------------------------------------------------- */

static void usart_up(void)
{
    model_init();
    wr(RCC_APB2ENR, (1u << 14) | (1u << 2));
    wr(GPIOA_CRH, 0x444448B4u); /* PA9 AF push-pull, PA10 pulled input */
    wr(USART_BRR, 833u);        /* 8 MHz (HSI, reset) / 833: 9604 baud */
    wr(USART_CR1, (1u << 13) | (1u << 3) | (1u << 2));
}

/* RXNE is cleared by reading DR; ORE (a byte lost while RXNE was set), FE, NE, PE only
 * by reading SR and then DR. BRR decodes into PCLK2 / BRR. */
static void usart_receive_flags(void **state)
{
    (void)state;
    usart_up();
    assert_int_equal(model_usart_bps(), 9603u);
    const uint8_t b[3] = {0x41, 0x42, 0x43};
    model_wire_send(b, 3, 9600);
    model_run(MODEL_MS(4));
    uint32_t sr = rd(USART_SR);
    assert_true(sr & 0x20u); /* RXNE */
    assert_true(sr & 0x08u); /* ORE: 0x42 and 0x43 lost */
    assert_int_equal(rd(USART_DR), 0x41);
    assert_false(rd(USART_SR) & 0x28u);
    /* DR read without SR before it: RXNE goes, ORE stays. */
    model_wire_send(b, 2, 9600);
    model_run(MODEL_MS(3));
    (void)rd(USART_DR);
    assert_true(rd(USART_SR) & 0x08u);
    assert_int_equal(rd(USART_DR), 0x41);
    assert_false(rd(USART_SR) & 0x08u);
    /* A byte sent at half the rate: its stop bit reads 0, a framing error. */
    const uint8_t z = 0x00;
    model_wire_send(&z, 1, 4800);
    model_run(MODEL_MS(3));
    assert_true(rd(USART_SR) & 0x02u);
    (void)rd(USART_DR);
    assert_false(rd(USART_SR) & 0x02u);
}

/* TXE falls when DR is written and rises when the byte moves to the shift register; TC
 * once the last stop bit is out, and it is cleared by SR read then DR write. */
static void usart_transmit_flags(void **state)
{
    (void)state;
    usart_up();
    model.usart.de_pin = 0x0C; /* PA12 */
    wr(GPIOA_CRH, 0x444248B4u);  /* and PA12 a push-pull output */
    model_run(MODEL_MS(20)); /* the idle frame TE sent */
    wr(GPIOA_BSRR, 1u << 12);  /* DE up */
    (void)rd(USART_SR);
    wr(USART_DR, 0x55);
    assert_false(rd(USART_SR) & 0x40u); /* TC cleared by SR read + DR write */
    assert_true(rd(USART_SR) & 0x80u);  /* TXE again: moved to the shift register */
    wr(USART_DR, 0xAA);
    assert_false(rd(USART_SR) & 0x80u);
    model_run(MODEL_MS(3));
    assert_true(rd(USART_SR) & 0x40u);
    assert_int_equal(model.usart.tx_len, 2);
    assert_int_equal(model.usart.tx[1].start, model.usart.tx[0].end); /* back to back */
    assert_int_equal(model.usart.tx[0].end - model.usart.tx[0].start,
                     10u * 833u * (MODEL_HZ / 8000000u));
    assert_true(model.usart.tx[0].de_all_along && model.usart.tx[1].de_all_along);
    assert_int_equal(model.violations, 0);
    /* DE released while a byte is on the wire: a violation. */
    wr(USART_DR, 0x01);
    wr(GPIOA_BSRR, 1u << 28);
    assert_int_equal(model.violations, 1);
}

/* ---- IWDG --------------------------------------------------------------------------- */

/* 0xCCCC starts it at LSI / 4 from 0xFFF; PR and RLR need the key 0x5555 and apply at
 * the next reload; not fed, it resets the chip (and the reset flags say so). */
static void iwdg_keys_and_timeout(void **state)
{
    (void)state;
    model_init();
    wr(IWDG_PR, 3u); /* without the key: ignored */
    assert_int_equal(model.violations, 1);
    wr(IWDG_KR, 0xCCCCu);
    wr(IWDG_KR, 0x5555u);
    wr(IWDG_PR, 3u);
    wr(IWDG_RLR, 312u);
    assert_true(rd(IWDG_SR) & 3u); /* PVU, RVU: crossing into the LSI domain */
    model_run(MODEL_MS(1));
    assert_false(rd(IWDG_SR) & 3u);
    wr(IWDG_KR, 0xAAAAu);
    uint64_t t0 = model.now;
    int why = model_catch(stopped);
    if (why == 0)
        for (;;)
            model_run(MODEL_MS(1));
    assert_int_equal(why, MODEL_EXIT_RESET);
    assert_true(model.now - t0 >= MODEL_US(250400) - MODEL_MS(1));
    assert_true(model.now - t0 <= MODEL_US(250400) + MODEL_MS(1));
    assert_true(model.rcc.csr & (1u << 29));
    assert_false(model.iwdg.on); /* a reset stops it (no hardware option) */
}

/* RM0008 IWDG_PR: 110 and 111 both divide by 256 (there is no /512). RLR 0: one count,
 * 256 / 40 kHz = 6.4 ms. */
static void iwdg_prescaler_7_divides_by_256(void **state)
{
    (void)state;
    model_init();
    wr(IWDG_KR, 0xCCCCu);
    wr(IWDG_KR, 0x5555u);
    wr(IWDG_PR, 7u);
    wr(IWDG_RLR, 0u);
    model_run(MODEL_MS(1));
    wr(IWDG_KR, 0xAAAAu);
    uint64_t t0 = model.now;
    int why = model_catch(stopped);
    if (why == 0)
        for (;;)
            model_run(MODEL_US(100));
    assert_int_equal(why, MODEL_EXIT_RESET);
    assert_true(model.now - t0 >= MODEL_US(6400) - MODEL_US(100));
    assert_true(model.now - t0 <= MODEL_US(6400) + MODEL_US(100));
}

/* ---- GPIO ------------------------------------------------------------------------- */

/* Reset: every pin a floating input. BSRR sets and resets (set wins), CRH selects. */
static void gpio_modes_and_bsrr(void **state)
{
    (void)state;
    model_init();
    assert_int_equal(model_pin_state(0x0C), MODEL_PIN_FLOATING);
    wr(GPIOA_CRH, 0x44424444u); /* clock off: ignored, a violation */
    assert_int_equal(model.violations, 1);
    assert_int_equal(model_pin_state(0x0C), MODEL_PIN_FLOATING);
    wr(RCC_APB2ENR, 1u << 2);
    wr(GPIOA_CRH, 0x44424444u);
    assert_int_equal(model_pin_state(0x0C), MODEL_PIN_LOW);
    wr(GPIOA_BSRR, (1u << 12) | (1u << 28)); /* both: set wins */
    assert_int_equal(model_pin_state(0x0C), MODEL_PIN_HIGH);
    wr(GPIOA_BSRR, 1u << 28);
    assert_int_equal(model_pin_state(0x0C), MODEL_PIN_LOW);
    wr(GPIOA_CRH, 0x44484444u);
    wr(GPIOA_ODR, 1u << 12);
    assert_int_equal(model_pin_state(0x0C), MODEL_PIN_PULL_UP);
    /* Open-drain output (CNF 01): a 0 pulls the pin low, a 1 lets it go (RM0008 §9.1.8):
     * a driver enable on it would float, not go high. */
    wr(GPIOA_CRH, 0x44464444u);
    assert_int_equal(model_pin_state(0x0C), MODEL_PIN_FLOATING);
    wr(GPIOA_BSRR, 1u << 28);
    assert_int_equal(model_pin_state(0x0C), MODEL_PIN_LOW);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(fpec_keys),
        cmocka_unit_test(fpec_program),
        cmocka_unit_test(fpec_erase),
        cmocka_unit_test(fpec_power_cut),
        cmocka_unit_test(usart_receive_flags),
        cmocka_unit_test(usart_transmit_flags),
        cmocka_unit_test(iwdg_keys_and_timeout),
        cmocka_unit_test(iwdg_prescaler_7_divides_by_256),
        cmocka_unit_test(gpio_modes_and_bsrr),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
