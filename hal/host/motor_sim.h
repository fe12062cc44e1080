/* motor_sim.h - simulated DC gearmotor behind the host HAL: an H-bridge driving a DC
 * motor (resistance, torque/back-EMF constant, supply) through a gearbox onto a load
 * (inertia, viscous and Coulomb friction), with an output encoder. Integrated lazily up
 * to the HAL clock whenever the core reads or drives it. Host only (uses double). */
#ifndef MOTOR_SIM_H
#define MOTOR_SIM_H

#include <stdbool.h>
#include <stdint.h>

struct motor_params {
    double supply_v;      /* H-bridge supply */
    double resistance;    /* winding, ohm */
    double kt;            /* N m / A at the motor = back-EMF V s / rad */
    double gear;          /* motor turns per output turn */
    double inertia;       /* kg m^2 at the output */
    double viscous;       /* N m s / rad at the output */
    double coulomb;       /* N m at the output */
    double gravity;       /* N m of a load's weight at the output, at angle 0 (cos law) */
    uint32_t counts_per_rev; /* encoder counts per output turn */
};

struct motor_sim {
    struct motor_params p;
    double theta;   /* output angle, rad */
    double omega;   /* output speed, rad/s */
    double current; /* A */
    int16_t duty;   /* last drive, per mille */
    bool enabled;
    uint32_t last_us;
    bool started;
    double travel;  /* total |angle| turned, rad (for tests: "did it move?") */
    bool blocked;   /* fault injection: the shaft is jammed */
};

/* A 12 V gearmotor whose output reaches about 1000 deg/s with no load. */
void motor_sim_init(struct motor_sim *m, uint32_t counts_per_rev);

/* Integrate from the last update up to now_us. */
void motor_sim_advance(struct motor_sim *m, uint32_t now_us);

/* Encoder count of the output (wrapping 32-bit). */
int32_t motor_sim_counts(const struct motor_sim *m);

#endif
