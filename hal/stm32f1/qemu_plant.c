/* qemu_plant.c - the QEMU build's motor and sensors (CMake preset `qemu`, in place of
 * motor.c): QEMU's stm32vldiscovery has no timers, ADC or GPIO inputs, so the arm's
 * plant is compiled into the image. It is the host's DC gearmotor (hal/host/motor_sim.c:
 * 12 V, 2 ohm, kt 0.01, gear 6, 2e-4 kg m^2, viscous 1e-3, Coulomb 0.01 N m) in integer
 * fixed point, with the arm's photo switches at 0 and 420 degrees and the shaft starting
 * at 90 degrees, as servo-sim's arm. No floating point: the image is checked for it like
 * every other.
 *
 * The plant is stepped from the control tick: every HAL call below (the tick reads the
 * position and switches, then drives) first integrates it up to hal_clock_us() in
 * steps of PLANT_STEP_US, semi-implicit Euler as on the host. Supply and temperature are
 * those of a healthy board at rest (12 V, 25 C). Main loop only. */
#include "hal_stm32f1.h"

/* Units: position in encoder counts x 2^16 (64-bit: 420 degrees is 19,115 counts),
 * speed in counts/s x 16, acceleration in counts/s^2 x 16. K = 16384 / 2 pi counts per
 * radian (the arm's encoder). */
#define PLANT_STEP_US 250u
#define STEPS_PER_S (1000000 / (int32_t)PLANT_STEP_US)
#define PLANT_CATCH_UP_US 200000u /* a longer pause (QEMU stopped) is skipped, not run */
/* Drive: kt gear / R x supply / 1000 / J = 1.8 rad/s^2 per mille of duty, x K x 16. */
#define ALPHA_PER_DUTY 75099
/* Damping, per second: back-EMF through the winding (kt gear)^2 / R / J = 9 while the
 * bridge drives, plus viscous friction 1e-3 / J = 5 always (a coasting bridge is open). */
#define DAMP_DRIVEN 14
#define DAMP_COAST 5
/* Coulomb friction 0.01 N m / J = 50 rad/s^2, x K x 16. */
#define FRICTION 2086075
/* Winding current in mA: (12 V x duty / 1000 - kt gear w) / R = 6 mA per mille of duty
 * less 30 mA per rad/s, i.e. speed (x 16) / 1391. */
#define MA_PER_DUTY 6
#define SPEED_PER_MA 1391
#define COUNTS_PER_REV 16384
#define START_Q16 ((int64_t)COUNTS_PER_REV / 4 << 16) /* 90 degrees */
/* Switch 2 reads interrupted from 420 degrees on: 19,114.67 counts, rounded up. */
#define SWITCH2_Q16 (((int64_t)420 * COUNTS_PER_REV << 16) / 360 + 1)
#define SUPPLY_MV 12000u
#define TEMPERATURE_DC 250

_Static_assert(BOARD_PHOTO && !BOARD_POSITION_POT, "the plant is the arm's: encoder, switches");

struct plant {
    int64_t pos_q16; /* output shaft */
    int32_t speed;   /* counts/s x 16 */
    int16_t duty;    /* last drive, per mille */
    uint8_t enabled; /* gate driver on */
    uint8_t started; /* last_us is valid */
    uint32_t last_us;
};

static struct plant plant;

/* One step of PLANT_STEP_US: friction holds a shaft at rest, and stops a turning one
 * without reversing it. */
static void plant_step(struct plant *p)
{
    bool driven = p->enabled && p->duty != 0;
    int32_t alpha = driven ? ALPHA_PER_DUTY * p->duty - DAMP_DRIVEN * p->speed
                           : -DAMP_COAST * p->speed;
    if (p->speed == 0 && alpha <= FRICTION && alpha >= -FRICTION)
        return;
    alpha -= (p->speed > 0 || (p->speed == 0 && alpha > 0)) ? FRICTION : -FRICTION;
    int32_t speed = p->speed + alpha / STEPS_PER_S;
    if ((p->speed > 0 && speed < 0) || (p->speed < 0 && speed > 0))
        speed = 0;
    p->speed = speed;
    /* counts x 16 per second for 1/4000 s, as counts x 2^16: x 4096 / 4000. */
    p->pos_q16 += speed * 128 / 125;
}

/* Integrate up to now. */
static void plant_advance(struct hal *h)
{
    struct plant *p = &plant;
    uint32_t now = hal_clock_us(h);
    if (!p->started || now - p->last_us > PLANT_CATCH_UP_US) {
        p->started = 1;
        p->last_us = now;
        return;
    }
    while (now - p->last_us >= PLANT_STEP_US) {
        p->last_us += PLANT_STEP_US;
        plant_step(p);
    }
}

void motor_init(struct hal *h, const struct board *b)
{
    h->board = b;
    plant = (struct plant){.pos_q16 = START_Q16};
}

void hal_motor_enable(struct hal *h, bool on)
{
    plant_advance(h);
    if (!on)
        plant.duty = 0;
    plant.enabled = on;
}

void hal_motor_drive(struct hal *h, int16_t duty)
{
    plant_advance(h);
    plant.duty = duty > HAL_DUTY_MAX ? HAL_DUTY_MAX : duty < -HAL_DUTY_MAX ? -HAL_DUTY_MAX : duty;
}

int32_t hal_motor_position(struct hal *h)
{
    plant_advance(h);
    return (int32_t)((plant.pos_q16 + 0x8000) >> 16);
}

uint16_t hal_motor_current_ma(struct hal *h)
{
    plant_advance(h);
    if (!plant.enabled || plant.duty == 0)
        return 0; /* coasting: the bridge is open */
    int32_t ma = MA_PER_DUTY * plant.duty - plant.speed / SPEED_PER_MA;
    return (uint16_t)(ma < 0 ? -ma : ma);
}

uint16_t hal_supply_mv(struct hal *h)
{
    (void)h;
    return SUPPLY_MV;
}

int16_t hal_temperature_dc(struct hal *h)
{
    (void)h;
    return TEMPERATURE_DC;
}

/* Switch 1 at 0 degrees (interrupted at and below it), switch 2 at 420 (at and above). */
uint8_t hal_photo_switches(struct hal *h)
{
    plant_advance(h);
    return (uint8_t)((plant.pos_q16 <= 0 ? 1u : 0u) | (plant.pos_q16 >= SWITCH2_Q16 ? 2u : 0u));
}
