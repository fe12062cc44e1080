/* motor.c - the H-bridge (TIM3 PWM, gate driver enable), the position sensor (TIM2 in
 * quadrature encoder mode, or a potentiometer on the ADC), the analog sensors (ADC1
 * scanning into RAM by DMA once every PWM period, triggered by TIM3, so a read never
 * waits) and the photo switches: everything the plant model (qemu_plant.c) stands in
 * for under QEMU. Main loop only.
 *
 * The current: the low-side shunt carries the winding current only while the bridge
 * drives (IN1 or IN2 high); between pulses, both low, the current decays through the
 * bridge and the shunt carries none. A sample at a random phase of the 20 kHz PWM reads
 * either. So TIM3 starts each scan (TRGO = OC4REF, CH4 in PWM mode 2, output off) such
 * that the current, converted first, holds its sample at the middle of the on-time: the
 * average of the current's ripple. hal_motor_current_ma() is the current during the
 * on-time. (The board needs no filter on it, and none slower than 0.5 us:
 * ref_pcb.h.) */
#include "hal_stm32f1.h"

/* ADC1 channel n is pin PAn for n < 8. */
_Static_assert(BOARD_ADC_CURRENT < 8u && BOARD_ADC_SUPPLY < 8u && BOARD_ADC_TEMP < 8u &&
                   BOARD_ADC_POT < 8u,
               "analog inputs on port A");
static uint8_t adc_pin(uint32_t channel)
{
    return PIN('A', channel);
}

static void pwm_init(struct hal *h)
{
    REG_SET(RCC->apb1enr, RCC_APB1ENR_TIM3EN);
    uint32_t period = h->tim_apb1_hz / BOARD_PWM_HZ; /* 72 MHz: 3600 steps at 20 kHz */
    if (period > 0x10000u)
        period = 0x10000u;
    h->pwm_period = (uint16_t)(period - 1u);
    REG_WRITE(TIM3->psc, 0);
    REG_WRITE(TIM3->arr, period - 1u);
    REG_WRITE(TIM3->ccr1, 0);
    REG_WRITE(TIM3->ccr2, 0);
    REG_WRITE(TIM3->ccr4, 1); /* the ADC's trigger (hal_motor_drive); CC4E stays off */
    REG_WRITE(TIM3->ccmr1,
              TIM_CCMR1_OC1_PWM1 | TIM_CCMR1_OC1PE | TIM_CCMR1_OC2_PWM1 | TIM_CCMR1_OC2PE);
    REG_WRITE(TIM3->ccmr2, TIM_CCMR2_OC4_PWM2 | TIM_CCMR2_OC4PE);
    REG_WRITE(TIM3->cr2, TIM_CR2_MMS_OC4REF);
    REG_WRITE(TIM3->ccer, TIM_CCER_CC1E | TIM_CCER_CC2E);
    REG_WRITE(TIM3->egr, TIM_EGR_UG);
    REG_WRITE(TIM3->cr1, TIM_CR1_ARPE | TIM_CR1_CEN);
    gpio_mode(BOARD_PIN_PWM_A, GPIO_AF_PP_50MHZ);
    gpio_mode(BOARD_PIN_PWM_B, GPIO_AF_PP_50MHZ);
}

static void encoder_init(struct hal *h)
{
    REG_SET(RCC->apb1enr, RCC_APB1ENR_TIM2EN);
    gpio_write(BOARD_PIN_ENC_A, true); /* open-collector encoders: pull-ups */
    gpio_write(BOARD_PIN_ENC_B, true);
    gpio_mode(BOARD_PIN_ENC_A, GPIO_IN_PULL);
    gpio_mode(BOARD_PIN_ENC_B, GPIO_IN_PULL);
    REG_WRITE(TIM2->arr, 0xFFFFu);
    REG_WRITE(TIM2->psc, 0);
    /* TI1 and TI2 as inputs, filtered over 8 samples of the timer clock. */
    REG_WRITE(TIM2->ccmr1, TIM_CCMR1_CC1S_TI1 | TIM_CCMR1_IC1F(3) | TIM_CCMR1_CC2S_TI2 |
                               TIM_CCMR1_IC2F(3));
    REG_WRITE(TIM2->ccer, BOARD_ENCODER_INVERT ? TIM_CCER_CC1P : 0u);
    REG_WRITE(TIM2->smcr, TIM_SMCR_SMS_ENCODER3);
    REG_WRITE(TIM2->cnt, 0);
    REG_WRITE(TIM2->cr1, TIM_CR1_CEN);
    h->enc_last = 0;
    h->enc_count = 0;
}

/* ADC1 scans its channels at every rising edge of TIM3's TRGO; DMA1 channel 1 copies
 * each result into adc[]. The current is sampled 13.5 cycles, the rest 41.5: a whole
 * scan (4 channels at most) takes 188 ADC cycles, 47 us on the 4 MHz ADC clock of the
 * 8 MHz fall-back, so each trigger of a 50 us period finds the ADC free. */
static void adc_init(struct hal *h)
{
    static const uint8_t channel[ADC_SLOTS] = {BOARD_ADC_CURRENT, BOARD_ADC_SUPPLY,
                                               BOARD_ADC_TEMP, BOARD_ADC_POT};
    REG_SET(RCC->apb2enr, RCC_APB2ENR_ADC1EN);
    REG_SET(RCC->ahbenr, RCC_AHBENR_DMA1EN);
    uint32_t sqr3 = 0, smpr2 = 0;
    for (uint32_t i = 0; i < ADC_COUNT; i++) {
        gpio_mode(adc_pin(channel[i]), GPIO_IN_ANALOG);
        sqr3 |= (uint32_t)channel[i] << (5u * i);
        smpr2 |= (i == ADC_CURRENT ? ADC_SMP_13 : ADC_SMP_41) << (3u * channel[i]);
    }
    REG_WRITE(DMA1->ch[0].ccr, 0);
    REG_WRITE(DMA1->ch[0].cpar, (uint32_t)(uintptr_t)&ADC1->dr);
    REG_WRITE(DMA1->ch[0].cmar, (uint32_t)(uintptr_t)h->adc);
    REG_WRITE(DMA1->ch[0].cndtr, ADC_COUNT);
    REG_WRITE(DMA1->ch[0].ccr,
              DMA_CCR_MINC | DMA_CCR_CIRC | DMA_CCR_PSIZE_16 | DMA_CCR_MSIZE_16);
    REG_SET(DMA1->ch[0].ccr, DMA_CCR_EN);
    REG_WRITE(ADC1->cr1, ADC_CR1_SCAN);
    REG_WRITE(ADC1->smpr2, smpr2);
    REG_WRITE(ADC1->sqr1, (ADC_COUNT - 1u) << 20);
    REG_WRITE(ADC1->sqr3, sqr3);
    REG_WRITE(ADC1->cr2, ADC_CR2_ADON); /* power up; at least 1 us before calibration */
    for (volatile uint32_t i = 0; i < h->cycles_per_us * 2u; i++) {
    }
    /* Calibrate; the bits clear when done (bounded: an emulator may never clear them). */
    REG_WRITE(ADC1->cr2, ADC_CR2_ADON | ADC_CR2_RSTCAL);
    for (uint32_t spins = 100000u; spins && (REG_READ(ADC1->cr2) & ADC_CR2_RSTCAL); spins--) {
    }
    REG_WRITE(ADC1->cr2, ADC_CR2_ADON | ADC_CR2_CAL);
    for (uint32_t spins = 100000u; spins && (REG_READ(ADC1->cr2) & ADC_CR2_CAL); spins--) {
    }
    /* The current's sample holds 15.5 ADC cycles after the trigger: 2 of latency
     * (datasheet, tlatr) and its 13.5 of sampling. In TIM3 counts: */
    uint32_t adc_hz = h->pclk2_hz /
                      (2u * (((REG_READ(RCC->cfgr) >> RCC_CFGR_ADCPRE_SHIFT) & 3u) + 1u));
    h->adc_lead = (uint16_t)(h->tim_apb1_hz * 31u / (2u * adc_hz));
    REG_WRITE(ADC1->cr2, ADC_CR2_ADON | ADC_CR2_DMA | ADC_CR2_EXTSEL_TIM3_TRGO |
                             ADC_CR2_EXTTRIG);
    if (h->clock_source == CLOCK_NO_RCC) {
        /* An emulator without RCC has no ADC or DMA either (QEMU's stm32vldiscovery):
         * adc[] keeps what is put here, a healthy board at rest (supply in the middle
         * of the board's range, 25 C, no current, potentiometer mid-scale). */
        uint32_t mv = (h->board->supply_min_mv + h->board->supply_max_mv) / 2u;
        h->adc[ADC_SUPPLY] = (uint16_t)((mv << 12) / BOARD_SUPPLY_MV_FS);
        h->adc[ADC_TEMP] = (uint16_t)(((BOARD_TEMP_MV_AT_0C + 250u * BOARD_TEMP_UV_PER_DC /
                                        1000u) << 12) / 3300u + 1u);
        h->adc[ADC_POT] = 2048u;
    }
}

void motor_init(struct hal *h, const struct board *b)
{
    h->board = b;
    /* Counts at the potentiometer's full scale: counts_per_rev x span / 360 degrees. */
    h->pot_counts_fs = b->counts_per_rev * BOARD_POT_SPAN_DDEG / 3600u;
    pwm_init(h);
    if (!BOARD_POSITION_POT)
        encoder_init(h);
    adc_init(h);
}

void hal_motor_enable(struct hal *h, bool on)
{
    if (!on)
        hal_motor_drive(h, 0);
    gpio_write(BOARD_PIN_DRIVER_EN, on);
}

/* IN1 = PWM, IN2 = low turns positive (and the mirror image negative); both low
 * between pulses lets the current decay through the bridge (coast). */
void hal_motor_drive(struct hal *h, int16_t duty)
{
    int32_t d = BOARD_MOTOR_INVERT ? -(int32_t)duty : duty;
    uint32_t mag = (uint32_t)(d < 0 ? -d : d);
    if (mag > HAL_DUTY_MAX)
        mag = HAL_DUTY_MAX;
    uint32_t ccr = mag * ((uint32_t)h->pwm_period + 1u) / HAL_DUTY_MAX;
    REG_WRITE(TIM3->ccr1, d > 0 ? ccr : 0u);
    REG_WRITE(TIM3->ccr2, d < 0 ? ccr : 0u);
    /* The scan starts adc_lead counts before the on-time's middle, so the current holds
     * there; never at 0 (PWM mode 2 would never rise: no scan at all). An on-time shorter
     * than twice the lead (5 % at 72 MHz) holds after its middle, or after it ends. */
    uint32_t mid = ccr / 2u;
    REG_WRITE(TIM3->ccr4, mid > h->adc_lead ? mid - h->adc_lead : 1u);
}

/* Encoder: the 16-bit timer extended to 32 bits by adding each signed 16-bit step; right
 * as long as the shaft moves less than 32767 counts between two calls (the control tick
 * calls every millisecond). Potentiometer: absolute, 0 at 0 V. */
int32_t hal_motor_position(struct hal *h)
{
    if (BOARD_POSITION_POT) {
        uint32_t raw = h->adc[ADC_POT];
        if (BOARD_POT_INVERT)
            raw = 4095u - raw;
        return (int32_t)(raw * h->pot_counts_fs >> 12);
    }
    uint16_t now = (uint16_t)REG_READ(TIM2->cnt);
    uint32_t step = (uint32_t)(int32_t)(int16_t)(uint16_t)(now - h->enc_last);
    h->enc_count += step;
    h->enc_last = now;
    return (int32_t)h->enc_count;
}

uint16_t hal_motor_current_ma(struct hal *h)
{
    return (uint16_t)(h->adc[ADC_CURRENT] * BOARD_CURRENT_MA_FS >> 12);
}

uint16_t hal_supply_mv(struct hal *h)
{
    return (uint16_t)(h->adc[ADC_SUPPLY] * BOARD_SUPPLY_MV_FS >> 12);
}

int16_t hal_temperature_dc(struct hal *h)
{
    int32_t mv = (int32_t)(h->adc[ADC_TEMP] * 3300u >> 12);
    int32_t dc = (mv - (int32_t)BOARD_TEMP_MV_AT_0C) * 1000 / (int32_t)BOARD_TEMP_UV_PER_DC;
    return (int16_t)dc;
}

uint8_t hal_photo_switches(struct hal *h)
{
    (void)h;
    if (!BOARD_PHOTO)
        return 0;
    bool s1 = gpio_read(BOARD_PIN_PHOTO1) == BOARD_PHOTO_ACTIVE_HIGH;
    bool s2 = gpio_read(BOARD_PIN_PHOTO2) == BOARD_PHOTO_ACTIVE_HIGH;
    return (uint8_t)(s1 | (s2 << 1));
}
