/* test_uart.c - the application's port on the models, with the whole core: USART1
 * (uart.c) receiving and sending for the servo, the RS485 driver enable against the
 * last stop bit (TC), RM0008's receive flags (overrun, framing error), the echo of a
 * single-wire transceiver, the bit rate BRR really makes on each clock, a fall-back
 * clock refusing what it cannot make, reception going on through a 300 ms erase, and the
 * watchdog fed by the main loop. The servo is brought up as hal/stm32f1/main.c does. */
#include "link.h"
#include "port_app.h"

static struct hal *const h = &hal_stm32;

static const uint8_t PING_ANSWER[] = {0xD5, 0x5D, 0x01, 0x03, 0x01, 0x00, 0x05};
#define ARM_DELAY_US 8000u /* register 5: 16 x 500 us */

/* Power-on and main.c's bring-up (the bootloader's part is port.boot's). */
static void app_up(bool crystal, bool pll)
{
    port_board_new(crystal, pll);
    port_application();
}

static bool loop_for(uint64_t ticks)
{
    return port_loop_for(ticks) == 0;
}

static uint16_t frame(uint8_t *out, uint8_t ins, const uint8_t *p, uint8_t n)
{
    return port_frame(out, 1, ins, p, n);
}

/* The host WRITEs one byte register of ID 1 at baud bps; the end of its last stop bit. */
static uint64_t host_write1(uint8_t addr, uint8_t value, uint32_t bps)
{
    uint8_t f[16];
    const uint8_t p[] = {addr, value};
    return port_host_send(f, frame(f, INS_WRITE, p, 2), bps);
}

/* ---- Receive and send ------------------------------------------------------------- */

/* A PING answered: after the return delay counted from the end of the request's last
 * stop bit; the driver enable up before the first start bit and down only after the
 * last stop bit (TC), promptly; low whenever nothing is sent. */
static void ping_answered_with_the_driver_enable_around_it(void **state)
{
    (void)state;
    app_up(true, true);
    assert_int_equal(model_pin_state(BOARD_PIN_RS485_DE), MODEL_PIN_LOW);
    assert_true(loop_for(MODEL_MS(20))); /* the idle frame TE sent at start-up is out */
    uint8_t f[8];
    uint64_t end = port_host_send(f, frame(f, INS_PING, 0, 0), 9600);
    assert_true(loop_for(MODEL_MS(40)));
    port_assert_answer(0, PING_ANSWER, sizeof PING_ANSWER);
    const struct model_tx *first = &model.usart.tx[0], *last = &model.usart.tx[6];
    uint64_t delay = first->start - end;
    assert_true(delay >= MODEL_US(ARM_DELAY_US - 1u) && delay <= MODEL_US(ARM_DELAY_US + 30u));
    uint64_t up = port_de_edge_after(end, MODEL_PIN_HIGH);
    uint64_t down = port_de_edge_after(end, MODEL_PIN_LOW);
    assert_true(up <= first->start);
    assert_true(first->start - up <= MODEL_US(5));
    assert_true(down >= last->end);            /* never before the last stop bit */
    assert_true(down - last->end <= MODEL_US(5)); /* and at once after it (TC) */
    assert_int_equal(model_pin_state(BOARD_PIN_RS485_DE), MODEL_PIN_LOW);
    assert_false(hal_uart_tx_busy(h));
    port_no_violation();
}

/* Return delay 0, at 9600: the answer comes as soon as it can, but never while the
 * host's last stop bit is still on the wire (RXNE comes half a bit, 52 us, earlier: the
 * two drivers would fight over the bus). The clock's resolution is 1 us. */
static void with_return_delay_0_the_answer_never_overlaps_the_request(void **state)
{
    (void)state;
    app_up(true, true);
    assert_true(loop_for(MODEL_MS(20)));
    uint8_t f[16];
    host_write1(REG_RETURN_DELAY, 0, 9600);
    assert_true(loop_for(MODEL_MS(40)));
    uint32_t from = model.usart.tx_len;
    uint64_t end = port_host_send(f, frame(f, INS_PING, 0, 0), 9600);
    assert_true(loop_for(MODEL_MS(20)));
    port_assert_answer(from, PING_ANSWER, sizeof PING_ANSWER);
    uint64_t up = port_de_edge_after(end - MODEL_MS(1), MODEL_PIN_HIGH);
    assert_true(up + MODEL_US(1) >= end);             /* not over the stop bit */
    assert_true(model.usart.tx[from].start - end <= MODEL_US(10)); /* but at once */
    port_no_violation();
}

/* At 1.8 Mbaud (code 10) too: DE around every byte, released after TC. Then a frame that
 * changes the baud is answered at the old rate, and the next one heard at the new. */
static void the_top_rate_and_a_baud_change(void **state)
{
    (void)state;
    app_up(true, true);
    assert_true(loop_for(MODEL_MS(20)));
    uint8_t f[16];
    host_write1(REG_BAUD_RATE, 10, 9600);
    assert_true(loop_for(MODEL_MS(40)));
    static const uint8_t ok[] = {0xD5, 0x5D, 0x01, 0x02, 0x00, 0x03};
    port_assert_answer(0, ok, sizeof ok);
    assert_int_equal(model_usart_bps(), 1800000u); /* 72 MHz / BRR 40: 0.45 % fast */
    uint32_t from = model.usart.tx_len;
    uint64_t end = port_host_send(f, frame(f, INS_PING, 0, 0), 1792000);
    assert_true(loop_for(MODEL_MS(20)));
    port_assert_answer(from, PING_ANSWER, sizeof PING_ANSWER);
    const struct model_tx *last = &model.usart.tx[model.usart.tx_len - 1u];
    assert_int_equal(last->end - model.usart.tx[from].start, 70u * 40u * 8u); /* BRR 40 */
    uint64_t down = port_de_edge_after(end, MODEL_PIN_LOW);
    assert_true(down >= last->end && down - last->end <= MODEL_US(5));
    port_no_violation();
}

/* RM0008: a byte arriving while RXNE is still set is lost (ORE), DR keeps the unread
 * one; reading SR then DR clears both. With the receive interrupt masked for three byte
 * times, the driver counts the overrun, hands the core the byte DR kept, and the
 * receiver works on: the next PING is answered. */
static void an_overrun_is_counted_and_cleared(void **state)
{
    (void)state;
    app_up(true, true);
    assert_true(loop_for(MODEL_MS(20)));
    const uint8_t junk[] = {0x11, 0x22, 0x33};
    model_wire_send(junk, 3, 9600);
    uint32_t irq = hal_irq_save(h);
    model_run(MODEL_MS(4));
    assert_true(model.usart.sr & USART_SR_ORE);
    hal_irq_restore(h, irq); /* the interrupt comes now */
    assert_int_equal(h->rx_overruns, 1);
    assert_false(model.usart.sr & (USART_SR_ORE | USART_SR_RXNE));
    assert_true(loop_for(MODEL_MS(10)));
    uint8_t f[8];
    port_host_send(f, frame(f, INS_PING, 0, 0), 9600);
    assert_true(loop_for(MODEL_MS(40)));
    port_assert_answer(0, PING_ANSWER, sizeof PING_ANSWER);
    port_no_violation();
}

/* A byte at the wrong rate breaks its stop bit (FE): dropped and counted, nothing else. */
static void a_framing_error_is_dropped(void **state)
{
    (void)state;
    app_up(true, true);
    assert_true(loop_for(MODEL_MS(20)));
    const uint8_t zero = 0x00;
    model_wire_send(&zero, 1, 4800);
    assert_true(loop_for(MODEL_MS(10)));
    assert_int_equal(h->rx_errors, 1);
    assert_false(model.usart.sr & USART_SR_FE);
    uint8_t f[8];
    port_host_send(f, frame(f, INS_PING, 0, 0), 9600);
    assert_true(loop_for(MODEL_MS(40)));
    port_assert_answer(0, PING_ANSWER, sizeof PING_ANSWER);
    port_no_violation();
}

/* A transceiver that hears itself: the answer comes back on RX while the servo sends. It
 * reads as a PING with a parameter, which the servo would answer with an instruction
 * error; it must not hear it at all. */
static void its_own_echo_is_not_heard(void **state)
{
    (void)state;
    app_up(true, true);
    model.usart.echo = true;
    assert_true(loop_for(MODEL_MS(20)));
    uint8_t f[8];
    port_host_send(f, frame(f, INS_PING, 0, 0), 9600);
    assert_true(loop_for(MODEL_MS(60)));
    port_assert_answer(0, PING_ANSWER, sizeof PING_ANSWER); /* one answer, nothing more */
    port_no_violation();
}

/* ---- The bit rate on each clock ------------------------------------------------------ */

/* BRR decoded by the model is what the driver says it makes (hal_uart_baud_achieved),
 * and within 2 % exactly for the codes the README lists per clock. */
static void brr_gives_the_rate_the_driver_reports(void **state)
{
    (void)state;
    static const struct {
        bool crystal, pll;
        uint8_t source;
        uint16_t reached; /* bit c: code c within 2 % */
    } clocks[] = {{true, true, CLOCK_HSE_PLL, 0x07FF},
                  {false, true, CLOCK_HSI_PLL, 0x07FF},
                  {false, false, CLOCK_HSI, 0x003F}};
    for (size_t c = 0; c < sizeof clocks / sizeof clocks[0]; c++) {
        app_up(clocks[c].crystal, clocks[c].pll);
        assert_int_equal(h->clock_source, clocks[c].source);
        assert_true(loop_for(MODEL_MS(30)));
        for (uint8_t code = 0; code <= 10; code++) {
            uint32_t want = link_baud(&board_arm, code);
            hal_uart_set_baud(h, want);
            uint32_t got = model_usart_bps();
            assert_int_equal(got, hal_uart_baud_achieved(h, want));
            uint32_t err = got > want ? got - want : want - got;
            assert_int_equal(err * 50u <= want, (clocks[c].reached >> code) & 1u);
        }
        port_no_violation();
    }
}

/* No crystal, no PLL: plain HSI, 8 MHz. Code 7 (896000: the USART tops out at 500 kBd) is
 * refused with an instruction error and the servo stays at 9600; code 5 is taken, and
 * the servo then answers at 256000 (0.8 % off). */
static void on_the_8_mhz_fall_back_the_top_codes_are_refused(void **state)
{
    (void)state;
    app_up(false, false);
    assert_int_equal(h->clock_source, CLOCK_HSI);
    assert_true(loop_for(MODEL_MS(100)));
    uint8_t f[16];
    host_write1(REG_BAUD_RATE, 7, 9600);
    assert_true(loop_for(MODEL_MS(40)));
    static const uint8_t refused[] = {0xD5, 0x5D, 0x01, 0x02, 0x20, 0x23};
    port_assert_answer(0, refused, sizeof refused);
    assert_int_equal(model_usart_bps(), 9603u);
    host_write1(REG_BAUD_RATE, 5, 9600);
    assert_true(loop_for(MODEL_MS(40)));
    uint32_t from = model.usart.tx_len;
    port_host_send(f, frame(f, INS_PING, 0, 0), 256000);
    assert_true(loop_for(MODEL_MS(20)));
    port_assert_answer(from, PING_ANSWER, sizeof PING_ANSWER);
    port_no_violation();
}

/* No crystal, the PLL on HSI: 64 MHz makes every code; 1792000 works (0.8 % slow). */
static void on_the_64_mhz_fall_back_every_code_works(void **state)
{
    (void)state;
    app_up(false, true);
    assert_int_equal(h->clock_source, CLOCK_HSI_PLL);
    assert_true(loop_for(MODEL_MS(30)));
    uint8_t f[16];
    host_write1(REG_BAUD_RATE, 10, 9600);
    assert_true(loop_for(MODEL_MS(40)));
    assert_int_equal(model_usart_bps(), 64000000u / 36u);
    uint32_t from = model.usart.tx_len;
    port_host_send(f, frame(f, INS_PING, 0, 0), 1792000);
    assert_true(loop_for(MODEL_MS(20)));
    port_assert_answer(from, PING_ANSWER, sizeof PING_ANSWER);
    port_no_violation();
}

/* Code 10 stored on the crystal, then a power-on with neither crystal nor PLL: the rate
 * comes out at BRR 16, 500 kBd (README). A host at 500000 finds the servo there and
 * writes code 5, which it takes; the servo then answers at 256000. */
static void a_stored_top_code_on_the_8_mhz_fall_back_is_found_at_500_kbd(void **state)
{
    (void)state;
    app_up(true, true);
    assert_true(loop_for(MODEL_MS(20)));
    uint8_t f[16];
    host_write1(REG_BAUD_RATE, 10, 9600);
    assert_true(loop_for(MODEL_MS(2000))); /* answered, switched, stored */
    assert_int_equal(model_usart_bps(), 1800000u);
    model.rcc.crystal = false;
    model.rcc.pll_locks = false;
    model_reset(MODEL_RESET_POWER);
    port_application();
    assert_int_equal(h->clock_source, CLOCK_HSI);
    assert_true(loop_for(MODEL_MS(100)));
    assert_int_equal(model_usart_bps(), 500000u);
    uint32_t from = model.usart.tx_len;
    port_host_send(f, frame(f, INS_PING, 0, 0), 500000);
    assert_true(loop_for(MODEL_MS(20)));
    port_assert_answer(from, PING_ANSWER, sizeof PING_ANSWER);
    const uint8_t baud5[] = {REG_BAUD_RATE, 5};
    from = model.usart.tx_len;
    port_host_send(f, frame(f, INS_WRITE, baud5, 2), 500000);
    assert_true(loop_for(MODEL_MS(40)));
    static const uint8_t ok[] = {0xD5, 0x5D, 0x01, 0x02, 0x00, 0x03};
    port_assert_answer(from, ok, sizeof ok);
    from = model.usart.tx_len;
    port_host_send(f, frame(f, INS_PING, 0, 0), 256000);
    assert_true(loop_for(MODEL_MS(20)));
    port_assert_answer(from, PING_ANSWER, sizeof PING_ANSWER);
    port_no_violation();
}

/* ---- While the flash is busy; the watchdog ------------------------------------------- */

/* A PING arrives during a 300 ms erase: the receive interrupt runs all along (the wait
 * is in RAM, interrupts are taken), the frame is whole once the erase ends, and it is
 * answered. */
static void a_frame_arriving_during_a_300_ms_erase_is_answered(void **state)
{
    (void)state;
    app_up(true, true);
    assert_true(loop_for(MODEL_MS(20)));
    model.fpec.erase_ticks = MODEL_MS(300);
    uint8_t f[8];
    model.usart.wire_free = model.now + MODEL_MS(100);
    port_host_send(f, frame(f, INS_PING, 0, 0), 9600);
    if (model_catch(port_stopped))
        fail_msg("reset during the erase");
    assert_true(hal_flash_erase(h, 0));
    model.exit = NULL;
    assert_int_equal(model.usart.tx_len, 0);
    assert_true(loop_for(MODEL_MS(20)));
    port_assert_answer(0, PING_ANSWER, sizeof PING_ANSWER);
    port_no_violation();
}

/* The IWDG as servo_init() sets it (key 0x5555, PR /32, RLR 312: 250 ms at 40 kHz): the
 * main loop feeds it for seconds; a main loop that stops is reset 250 ms later. */
static void the_main_loop_feeds_the_watchdog_and_a_hang_resets(void **state)
{
    (void)state;
    app_up(true, true);
    assert_true(model.iwdg.on);
    assert_int_equal(model.iwdg.pr, 3);
    assert_int_equal(model.iwdg.rlr, 312);
    assert_true(loop_for(MODEL_MS(2000)));
    assert_int_equal(model.resets, 1); /* power-on only */
    uint64_t t0 = model.now;
    if (model_catch(port_stopped) == 0)
        for (;;)
            model_run(MODEL_MS(1)); /* hung: nothing feeds it */
    assert_int_equal(model.resets, 2);
    assert_true(model.rcc.csr & (1u << 29)); /* IWDGRSTF */
    uint64_t after = model.now - t0;
    assert_true(after >= MODEL_MS(249) && after <= MODEL_MS(252));
    port_no_violation();
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(ping_answered_with_the_driver_enable_around_it),
        cmocka_unit_test(with_return_delay_0_the_answer_never_overlaps_the_request),
        cmocka_unit_test(the_top_rate_and_a_baud_change),
        cmocka_unit_test(an_overrun_is_counted_and_cleared),
        cmocka_unit_test(a_framing_error_is_dropped),
        cmocka_unit_test(its_own_echo_is_not_heard),
        cmocka_unit_test(brr_gives_the_rate_the_driver_reports),
        cmocka_unit_test(on_the_8_mhz_fall_back_the_top_codes_are_refused),
        cmocka_unit_test(on_the_64_mhz_fall_back_every_code_works),
        cmocka_unit_test(a_stored_top_code_on_the_8_mhz_fall_back_is_found_at_500_kbd),
        cmocka_unit_test(a_frame_arriving_during_a_300_ms_erase_is_answered),
        cmocka_unit_test(the_main_loop_feeds_the_watchdog_and_a_hang_resets),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
