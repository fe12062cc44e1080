/* motion_trace.c - moves of a foot on the host gearmotor model, for `make bench` and the
 * docs: the time each move of a table takes against the ideal trapezoid, and with --csv
 * the trace of one move (time, ideal, reference and measured position and speed). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dispatch.h"
#include "write.h"
#include "hal_host.h"
#include "servo.h"

static struct hal hal;
static struct servo s;

static void write16(uint8_t addr, uint16_t v)
{
    uint8_t d[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    write_registers(&s, addr, d, 2);
}

/* Ideal trapezoid (continuous): position and speed at time t of a move of dist degrees. */
static void ideal(double dist, double v, double a, double d, double t, double *pos, double *vel)
{
    double ta = v / a, td = v / d;
    if (v * v / (2 * a) + v * v / (2 * d) > dist) { /* triangle */
        v = sqrt(2 * dist * a * d / (a + d));
        ta = v / a;
        td = v / d;
    }
    double tc = (dist - v * ta / 2 - v * td / 2) / v;
    if (t < ta) {
        *vel = a * t;
        *pos = a * t * t / 2;
    } else if (t < ta + tc) {
        *vel = v;
        *pos = v * ta / 2 + v * (t - ta);
    } else if (t < ta + tc + td) {
        double u = t - ta - tc;
        *vel = v - d * u;
        *pos = v * ta / 2 + v * tc + v * u - d * u * u / 2;
    } else {
        *vel = 0;
        *pos = dist;
    }
}

static double ideal_time(double dist, double v, double a, double d)
{
    if (v * v / (2 * a) + v * v / (2 * d) > dist) {
        double vp = sqrt(2 * dist * a * d / (a + d));
        return vp / a + vp / d;
    }
    return dist / v + v / (2 * a) + v / (2 * d);
}

/* Run one move from rest at 0; returns the time until the shaft is within one count of
 * the goal and the move has ended, in seconds. */
static double move(int dist, int speed, int acc, int dec, FILE *csv)
{
    hal_host_init(&hal);
    servo_init(&s, &board_foot, &hal);
    s.regs.mem[REG_HEARTBEAT_ENABLE] = 0; /* no host talks here: the heartbeat would stop it */
    write16(REG_CCW_LIMIT, 3600);
    s.regs.mem[REG_ACCELERATION] = (uint8_t)acc;
    s.regs.mem[REG_DECELERATION] = (uint8_t)dec;
    write16(REG_MOVING_SPEED, (uint16_t)speed);
    write16(REG_GOAL_POSITION, (uint16_t)dist);
    int64_t goal = ((int64_t)dist * 16384 + 180) / 360;
    double done = -1;
    for (uint32_t us = 0; us < 20000000u; us += 100u) {
        hal.now_us += 100u;
        servo_poll(&s);
        if (csv && us % 5000u == 0u) {
            double ip, iv, t = us * 1e-6;
            ideal(dist, speed, acc * 10.0, dec * 10.0, t, &ip, &iv);
            fprintf(csv, "%.4f,%.3f,%.3f,%.3f,%.2f,%.2f\n", t, ip,
                    (double)(s.motion.plan.pos >> PLANNER_SHIFT) * 360.0 / 16384,
                    s.motion.ctl.counts * 360.0 / 16384, iv, hal.motor.omega * 57.29578);
        }
        if (done < 0 && !s.regs.mem[REG_MOVING] && llabs(s.motion.ctl.counts - goal) <= 1)
            done = us * 1e-6;
        if (done >= 0 && (!csv || us * 1e-6 > done + 0.3))
            break;
    }
    return done;
}

int main(int argc, char **argv)
{
    if (argc >= 3 && strcmp(argv[1], "--csv") == 0) {
        FILE *f = fopen(argv[2], "w");
        if (!f)
            return 1;
        fprintf(f, "t,ideal_pos,ref_pos,pos,ideal_speed,speed\n");
        move(argc > 3 ? 300 : 180, argc > 3 ? 1000 : 360, argc > 3 ? 255 : 72, argc > 3 ? 255 : 36, f);
        fclose(f);
        return 0;
    }
    static const int table[][4] = {
        {90, 180, 36, 36}, {360, 720, 72, 72}, {10, 300, 36, 36}, {180, 360, 72, 36},
        {45, 30, 36, 36}, {5, 6, 10, 10}, {300, 1000, 255, 255},
    };
    printf("== moves of a foot on the host gearmotor model (settled = within 1 count)\n");
    printf("%8s %8s %8s %8s %9s %9s %7s\n", "deg", "deg/s", "acc", "dec", "ideal s", "move s",
           "ratio");
    for (size_t i = 0; i < sizeof table / sizeof table[0]; i++) {
        const int *m = table[i];
        double t = move(m[0], m[1], m[2], m[3], 0);
        double ti = ideal_time(m[0], m[1], m[2] * 10.0, m[3] * 10.0);
        printf("%8d %8d %8d %8d %9.3f %9.3f %7.3f\n", m[0], m[1], m[2] * 10, m[3] * 10, ti, t,
               t / ti);
    }
    return 0;
}
