/* test_motor.c - hal/stm32f1/motor.c on the timer, ADC and GPIO models, for the board it
 * is built for (arm: encoder and photo switches; wrist: potentiometer): the H-bridge's
 * 20 kHz PWM on TIM3, the current sampled where it means something (the middle of the
 * PWM's on-time, by TIM3 triggering the ADC), the other analog inputs, the encoder on
 * TIM2 extended past 16 bits, the photo switches. On every clock the port can run on. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "hal_stm32f1.h"
#include "model.h"
#include "port_board.h"

static struct hal *const h = &hal_stm32;

static void no_violation(void)
{
    if (model.violations)
        fail_msg("%u violation(s), the first: %s", model.violations, model.violation);
}

/* Power-on, main.c's clock and pins, then motor_init() for the board under test. */
static void motor_up(bool crystal, bool pll)
{
    model_init();
    model.rcc.crystal = crystal;
    model.rcc.pll_locks = pll;
    model.adc.analog = port_board_analog;
    memset(h, 0, sizeof *h);
    gpio_init();
    clock_init(h);
    motor_init(h, &SERVO_BOARD);
}

static uint32_t tim3(uint32_t offset)
{
    return model.tim.reg[1][offset / 4u];
}

enum { CR2 = 0x04, CCMR1 = 0x18, CCMR2 = 0x1C, CCER = 0x20, PSC = 0x28, ARR = 0x2C,
       CCR1 = 0x34, CCR2 = 0x38, CCR4 = 0x40 };

/* ---- PWM ----------------------------------------------------------------------------- */

static void the_bridge_is_driven_at_20_khz(void **state)
{
    (void)state;
    static const struct {
        bool crystal, pll;
        uint32_t tim_hz;
    } clocks[] = {{true, true, 72000000u}, {false, true, 64000000u}, {false, false, 8000000u}};
    for (size_t c = 0; c < sizeof clocks / sizeof clocks[0]; c++) {
        motor_up(clocks[c].crystal, clocks[c].pll);
        assert_int_equal(model_tim_apb1_hz(), clocks[c].tim_hz);
        assert_int_equal(clocks[c].tim_hz / (tim3(PSC) + 1u) / (tim3(ARR) + 1u), 20000u);
        /* CH1 and CH2: PWM mode 1, preloaded, outputs on, on their pins. */
        assert_int_equal(tim3(CCMR1) & 0x7878u, 0x6868u);
        assert_int_equal(tim3(CCER) & 0x11u, 0x11u);
        assert_int_equal(model_pin_state(BOARD_PIN_PWM_A), MODEL_PIN_ALT);
        assert_int_equal(model_pin_state(BOARD_PIN_PWM_B), MODEL_PIN_ALT);
        /* Coast at start: both compares 0, the driver asleep. */
        assert_int_equal(tim3(CCR1), 0);
        assert_int_equal(tim3(CCR2), 0);
        assert_int_equal(model_pin_state(BOARD_PIN_DRIVER_EN), MODEL_PIN_LOW);
        uint32_t period = tim3(ARR) + 1u;
        hal_motor_enable(h, true);
        assert_int_equal(model_pin_state(BOARD_PIN_DRIVER_EN), MODEL_PIN_HIGH);
        hal_motor_drive(h, 500); /* half of the supply, positive: IN1 */
        assert_int_equal(tim3(CCR1), period / 2u);
        assert_int_equal(tim3(CCR2), 0);
        hal_motor_drive(h, -250);
        assert_int_equal(tim3(CCR1), 0);
        assert_int_equal(tim3(CCR2), period / 4u);
        hal_motor_drive(h, -HAL_DUTY_MAX * 2); /* clamped */
        assert_int_equal(tim3(CCR2), period);
        hal_motor_enable(h, false);
        assert_int_equal(tim3(CCR1), 0);
        assert_int_equal(tim3(CCR2), 0);
        assert_int_equal(model_pin_state(BOARD_PIN_DRIVER_EN), MODEL_PIN_LOW);
        no_violation();
    }
}

/* ---- Current sampling ------------------------------------------------------------- */

/* The low-side shunt carries the winding current only while the bridge drives; while
 * both inputs are low it carries nothing. A reading taken at a random phase of the
 * 20 kHz PWM is the on-time current or 0, at random. The port triggers the ADC from
 * TIM3 so that the current's sample holds at the middle of the on-time, the average of
 * the current's ripple: every reading is the on-time current. */
static void the_current_is_sampled_at_the_middle_of_the_on_time(void **state)
{
    (void)state;
    static const struct {
        bool crystal, pll;
    } clocks[] = {{true, true}, {false, true}, {false, false}};
    static const int16_t duty[] = {250, 500, 750, 950, -300, -600, 100};
    for (size_t c = 0; c < sizeof clocks / sizeof clocks[0]; c++) {
        motor_up(clocks[c].crystal, clocks[c].pll);
        hal_motor_enable(h, true);
        port_shunt_ma = 2000u;
        uint32_t period = tim3(ARR) + 1u;
        /* 10 % (the last) only on the PLL clocks: at 8 MHz its on-time, 5 us, is shorter
         * than the trigger's lead (2 + 13.5 ADC cycles at 4 MHz, 3.9 us, before the
         * middle), so the sample holds later than the middle (still inside the on-time). */
        size_t duties = sizeof duty / sizeof duty[0] - (clocks[c].pll ? 0u : 1u);
        for (size_t d = 0; d < duties; d++) {
            hal_motor_drive(h, duty[d]);
            uint32_t on = (uint32_t)abs(duty[d]) * period / HAL_DUTY_MAX;
            model_run(MODEL_US(200)); /* a few periods for the new duty */
            uint32_t ignored = model.adc.triggers_ignored, scans = model.adc.conversions;
            for (int k = 0; k < 40; k++) {
                model_run(MODEL_US(37)); /* readings at every phase of the PWM */
                uint32_t ma = hal_motor_current_ma(h);
                if (ma < 1990u || ma > 2010u)
                    fail_msg("clock %zu, duty %d: read %u mA, the on-time carries 2000", c,
                             duty[d], ma);
            }
            /* A scan every PWM period: each fits in one (47 us at most, on the 4 MHz ADC
             * of the 8 MHz fall-back), so no trigger comes while the ADC is busy. (Right
             * after a large cut of the duty, one trigger may: one sample a period old.) */
            assert_int_equal(model.adc.triggers_ignored, ignored);
            uint32_t done = (model.adc.conversions - scans) / ADC_COUNT;
            assert_true(done == 40u * 37u / 50u || done == 40u * 37u / 50u + 1u); /* 29.6 */
            /* Where the current channel's last sample held: the on-time's middle. */
            assert_true(model.now - model.adc.hold[BOARD_ADC_CURRENT] < MODEL_US(60));
            uint32_t at = model_tim3_counter(model.adc.hold[BOARD_ADC_CURRENT]);
            if (at + 1u < on / 2u || at > on / 2u + 1u)
                fail_msg("clock %zu, duty %d: sample held at count %u, the middle is %u", c,
                         duty[d], at, on / 2u);
        }
        no_violation();
    }
}

/* The configuration the sampling rests on: ADC1's regular scan started by TIM3's TRGO
 * (EXTSEL 100, RM0008 table 69) rather than running free; TRGO = OC4REF, CH4 in PWM
 * mode 2 (rising where CNT reaches CCR4) with its output off (PB1 is the terminator's
 * pin); the current first, sampled briefly (a low-impedance amplifier output), the
 * rest long enough for their dividers; DMA circular over the scan. */
static void the_adc_is_triggered_from_tim3(void **state)
{
    (void)state;
    motor_up(true, true);
    uint32_t cr2 = model.adc.reg[2];
    assert_int_equal((cr2 >> 17) & 7u, 4u);   /* EXTSEL: TIM3_TRGO */
    assert_true(cr2 & (1u << 20));           /* EXTTRIG */
    assert_false(cr2 & (1u << 1));           /* not continuous */
    assert_true(cr2 & (1u << 8));            /* DMA */
    assert_int_equal((tim3(CR2) >> 4) & 7u, 7u); /* MMS: OC4REF */
    assert_int_equal((tim3(CCMR2) >> 12) & 7u, 7u); /* OC4M: PWM mode 2 */
    assert_int_equal(tim3(CCMR2) & 3u, 0u);      /* CC4: output compare */
    assert_false(tim3(CCER) & (1u << 12));       /* CC4E off: PB1 stays the GPIO's */
    assert_int_equal(model.adc.reg[13] & 0x1Fu, BOARD_ADC_CURRENT); /* first in the scan */
    uint32_t smpr2 = model.adc.reg[4];
    assert_int_equal((smpr2 >> (3u * BOARD_ADC_CURRENT)) & 7u, 2u); /* 13.5 cycles */
    assert_int_equal((smpr2 >> (3u * BOARD_ADC_SUPPLY)) & 7u, 4u);  /* 41.5 cycles */
    assert_int_equal((smpr2 >> (3u * BOARD_ADC_TEMP)) & 7u, 4u);
    assert_true(model.adc.dma_ccr & 1u);
    assert_int_equal(model.adc.dma_cndtr, ADC_COUNT);
    assert_int_equal(model.adc.dma_cmar, (uint32_t)(uintptr_t)h->adc);
    assert_int_equal(model_pin_state(BOARD_PIN_RS485_TERM), MODEL_PIN_LOW);
    no_violation();
}

/* Supply and temperature read back through their scaling, the motor at rest (the
 * triggers keep coming with the duty at 0). */
static void supply_and_temperature_read_right(void **state)
{
    (void)state;
    motor_up(true, true);
    port_supply_mv = 15000u;
    model_run(MODEL_MS(1));
    uint16_t mv = hal_supply_mv(h);
    assert_true(mv >= 14990u && mv <= 15010u);
    int16_t dc = hal_temperature_dc(h);
    assert_true(dc >= 249 && dc <= 251);
    assert_int_equal(hal_motor_current_ma(h), 0);
    port_supply_mv = 12000u;
    no_violation();
}

/* ---- Position and switches -------------------------------------------------------- */

static void the_position_sensor_reads_the_shaft(void **state)
{
    (void)state;
    motor_up(true, true);
    if (BOARD_POSITION_POT) {
        /* The wiper at mid-scale: half the span's counts. */
        model_run(MODEL_MS(1));
        int32_t p = hal_motor_position(h);
        int32_t want = (int32_t)(h->pot_counts_fs / 2u);
        assert_true(p >= want - 2 && p <= want + 2);
        no_violation();
        return;
    }
    /* TIM2 in encoder mode 3, both inputs, filtered; pulled up. */
    assert_int_equal(model.tim.reg[0][2] & 7u, 3u);
    assert_int_equal(model.tim.reg[0][6] & 0x303u, 0x101u);
    assert_int_equal(model_pin_state(BOARD_PIN_ENC_A), MODEL_PIN_PULL_UP);
    assert_int_equal(model_pin_state(BOARD_PIN_ENC_B), MODEL_PIN_PULL_UP);
    /* Three turns forward in 10,000-edge steps (the 16-bit counter wraps twice), back. */
    int32_t pos = 0;
    for (int i = 0; i < 20; i++) {
        model_encoder_edges(10000);
        pos += 10000;
        assert_int_equal(hal_motor_position(h), pos);
    }
    for (int i = 0; i < 25; i++) {
        model_encoder_edges(-10000);
        pos -= 10000;
        assert_int_equal(hal_motor_position(h), pos);
    }
    assert_int_equal(pos, -50000);
    no_violation();
}

static void the_photo_switches_read_interrupted_when_high(void **state)
{
    (void)state;
    motor_up(true, true);
    if (!BOARD_PHOTO) {
        assert_int_equal(hal_photo_switches(h), 0);
        return;
    }
    /* Pulled up: a wire that comes off reads "interrupted". */
    assert_int_equal(model_pin_state(BOARD_PIN_PHOTO1), MODEL_PIN_PULL_UP);
    assert_int_equal(hal_photo_switches(h), 3);
    model_pin_drive(BOARD_PIN_PHOTO1, 0);
    model_pin_drive(BOARD_PIN_PHOTO2, 0);
    assert_int_equal(hal_photo_switches(h), 0);
    model_pin_drive(BOARD_PIN_PHOTO2, 1);
    assert_int_equal(hal_photo_switches(h), 2);
    model_pin_drive(BOARD_PIN_PHOTO1, -1);
    model_pin_drive(BOARD_PIN_PHOTO2, -1);
    no_violation();
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(the_bridge_is_driven_at_20_khz),
        cmocka_unit_test(the_current_is_sampled_at_the_middle_of_the_on_time),
        cmocka_unit_test(the_adc_is_triggered_from_tim3),
        cmocka_unit_test(supply_and_temperature_read_right),
        cmocka_unit_test(the_position_sensor_reads_the_shaft),
        cmocka_unit_test(the_photo_switches_read_interrupted_when_high),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
