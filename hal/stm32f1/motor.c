/* motor.c - the H-bridge (TIM3 PWM, gate driver enable), the position sensor (TIM2 in
 * quadrature encoder mode, or a potentiometer on the ADC), the analog sensors (ADC1
 * scanning continuously into RAM by DMA, so a read never waits) and the photo switches:
 * everything the plant model (qemu_plant.c) stands in for under QEMU. Main loop only. */
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
    RCC->apb1enr |= RCC_APB1ENR_TIM3EN;
    uint32_t period = h->tim_apb1_hz / BOARD_PWM_HZ; /* 72 MHz: 3600 steps at 20 kHz */
    if (period > 0x10000u)
        period = 0x10000u;
    h->pwm_period = (uint16_t)(period - 1u);
    TIM3->psc = 0;
    TIM3->arr = period - 1u;
    TIM3->ccr1 = 0;
    TIM3->ccr2 = 0;
    TIM3->ccmr1 = TIM_CCMR1_OC1_PWM1 | TIM_CCMR1_OC1PE | TIM_CCMR1_OC2_PWM1 | TIM_CCMR1_OC2PE;
    TIM3->ccer = TIM_CCER_CC1E | TIM_CCER_CC2E;
    TIM3->egr = TIM_EGR_UG;
    TIM3->cr1 = TIM_CR1_ARPE | TIM_CR1_CEN;
    gpio_mode(BOARD_PIN_PWM_A, GPIO_AF_PP_50MHZ);
    gpio_mode(BOARD_PIN_PWM_B, GPIO_AF_PP_50MHZ);
}

static void encoder_init(struct hal *h)
{
    RCC->apb1enr |= RCC_APB1ENR_TIM2EN;
    gpio_write(BOARD_PIN_ENC_A, true); /* open-collector encoders: pull-ups */
    gpio_write(BOARD_PIN_ENC_B, true);
    gpio_mode(BOARD_PIN_ENC_A, GPIO_IN_PULL);
    gpio_mode(BOARD_PIN_ENC_B, GPIO_IN_PULL);
    TIM2->arr = 0xFFFFu;
    TIM2->psc = 0;
    /* TI1 and TI2 as inputs, filtered over 8 samples of the timer clock. */
    TIM2->ccmr1 = TIM_CCMR1_CC1S_TI1 | TIM_CCMR1_IC1F(3) | TIM_CCMR1_CC2S_TI2 |
                  TIM_CCMR1_IC2F(3);
    TIM2->ccer = BOARD_ENCODER_INVERT ? TIM_CCER_CC1P : 0u;
    TIM2->smcr = TIM_SMCR_SMS_ENCODER3;
    TIM2->cnt = 0;
    TIM2->cr1 = TIM_CR1_CEN;
    h->enc_last = 0;
    h->enc_count = 0;
}

/* ADC1 scans its channels without end; DMA1 channel 1 copies each result into adc[]. */
static void adc_init(struct hal *h)
{
    static const uint8_t channel[ADC_SLOTS] = {BOARD_ADC_CURRENT, BOARD_ADC_SUPPLY,
                                               BOARD_ADC_TEMP, BOARD_ADC_POT};
    RCC->apb2enr |= RCC_APB2ENR_ADC1EN;
    RCC->ahbenr |= RCC_AHBENR_DMA1EN;
    uint32_t sqr3 = 0, smpr2 = 0;
    for (uint32_t i = 0; i < ADC_COUNT; i++) {
        gpio_mode(adc_pin(channel[i]), GPIO_IN_ANALOG);
        sqr3 |= (uint32_t)channel[i] << (5u * i);
        smpr2 |= ADC_SMP_239 << (3u * channel[i]);
    }
    DMA1->ch[0].ccr = 0;
    DMA1->ch[0].cpar = (uint32_t)(uintptr_t)&ADC1->dr;
    DMA1->ch[0].cmar = (uint32_t)(uintptr_t)h->adc;
    DMA1->ch[0].cndtr = ADC_COUNT;
    DMA1->ch[0].ccr = DMA_CCR_MINC | DMA_CCR_CIRC | DMA_CCR_PSIZE_16 | DMA_CCR_MSIZE_16;
    DMA1->ch[0].ccr |= DMA_CCR_EN;
    ADC1->cr1 = ADC_CR1_SCAN;
    ADC1->smpr2 = smpr2;
    ADC1->sqr1 = (ADC_COUNT - 1u) << 20;
    ADC1->sqr3 = sqr3;
    ADC1->cr2 = ADC_CR2_ADON; /* power up; at least 1 us before calibration */
    for (volatile uint32_t i = 0; i < h->cycles_per_us * 2u; i++) {
    }
    /* Calibrate; the bits clear when done (bounded: an emulator may never clear them). */
    ADC1->cr2 = ADC_CR2_ADON | ADC_CR2_RSTCAL;
    for (uint32_t spins = 100000u; spins && (ADC1->cr2 & ADC_CR2_RSTCAL); spins--) {
    }
    ADC1->cr2 = ADC_CR2_ADON | ADC_CR2_CAL;
    for (uint32_t spins = 100000u; spins && (ADC1->cr2 & ADC_CR2_CAL); spins--) {
    }
    uint32_t run = ADC_CR2_ADON | ADC_CR2_CONT | ADC_CR2_DMA | ADC_CR2_EXTSEL_SWSTART |
                   ADC_CR2_EXTTRIG;
    ADC1->cr2 = run;
    ADC1->cr2 = run | ADC_CR2_SWSTART;
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
    TIM3->ccr1 = d > 0 ? ccr : 0u;
    TIM3->ccr2 = d < 0 ? ccr : 0u;
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
    uint16_t now = (uint16_t)TIM2->cnt;
    h->enc_count += (uint32_t)(int32_t)(int16_t)(uint16_t)(now - h->enc_last);
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
