/* motor_sim.c - DC gearmotor model (see motor_sim.h). */
#include <math.h>

#include "hal.h"
#include "motor_sim.h"

#define TWO_PI 6.283185307179586

void motor_sim_init(struct motor_sim *m, uint32_t counts_per_rev)
{
    *m = (struct motor_sim){0};
    m->p.supply_v = 12.0;
    m->p.resistance = 2.0;
    m->p.kt = 0.01;
    m->p.gear = 6.0;      /* no-load: 12 V / (0.01 * 6) = 200 rad/s ~ 11,000 deg/s at the motor */
    m->p.inertia = 2e-4;
    m->p.viscous = 1e-3;
    m->p.coulomb = 0.01;
    m->p.counts_per_rev = counts_per_rev;
}

/* One integration step of dt seconds (semi-implicit Euler). */
static void step(struct motor_sim *m, double dt)
{
    const struct motor_params *p = &m->p;
    double volts = m->enabled ? p->supply_v * m->duty / HAL_DUTY_MAX : 0.0;
    double back_emf = p->kt * p->gear * m->omega;
    /* Coasting (duty 0 or disabled): the bridge is open, no current flows back. */
    m->current = (m->enabled && m->duty) ? (volts - back_emf) / p->resistance : 0.0;
    double torque = p->kt * m->current * p->gear - p->viscous * m->omega -
                    p->gravity * cos(m->theta);
    double friction = p->coulomb;
    if (m->blocked) {
        m->omega = 0.0;
        m->current = m->enabled ? volts / p->resistance : 0.0;
        return;
    }
    if (fabs(m->omega) < 1e-6 && fabs(torque) <= friction) {
        m->omega = 0.0; /* static friction holds */
        return;
    }
    torque -= m->omega > 0 || (m->omega == 0 && torque > 0) ? friction : -friction;
    double omega = m->omega + torque / p->inertia * dt;
    if ((m->omega > 0 && omega < 0) || (m->omega < 0 && omega > 0))
        omega = 0.0; /* friction stops, never reverses */
    m->omega = omega;
    m->theta += omega * dt;
    m->travel += fabs(omega * dt);
}

/* Standing still, no drive, and friction (or a jam) holds the load: step() would change
 * nothing but set the current to 0, so an idle servo skips the integration (simulated
 * idle time about 100x faster). */
static bool at_rest(const struct motor_sim *m)
{
    if (m->omega != 0.0 || (m->enabled && m->duty))
        return false;
    return m->blocked || fabs(m->p.gravity * cos(m->theta)) <= m->p.coulomb;
}

void motor_sim_advance(struct motor_sim *m, uint32_t now_us)
{
    if (!m->started) {
        m->started = true;
        m->last_us = now_us;
        return;
    }
    uint32_t dt_us = now_us - m->last_us;
    m->last_us = now_us;
    if (dt_us && at_rest(m)) {
        m->current = 0.0; /* what every step() would leave: nothing else changes */
        m->omega = 0.0;
        return;
    }
    while (dt_us) {
        uint32_t d = dt_us > 50u ? 50u : dt_us;
        step(m, d * 1e-6);
        dt_us -= d;
    }
}

int32_t motor_sim_counts(const struct motor_sim *m)
{
    double counts = m->theta / TWO_PI * m->p.counts_per_rev;
    return (int32_t)(int64_t)llround(counts);
}
