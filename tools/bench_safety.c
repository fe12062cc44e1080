/* bench_safety.c - `make bench` figures of the safety layer on the host gearmotor:
 * fault-to-torque-off latency per fault, and heartbeat-expiry-to-stop latency, in
 * control ticks (1 ms). */
#include <stdio.h>

#include "dispatch.h"
#include "write.h"
#include "hal_host.h"
#include "servo.h"

static struct hal hal;
static struct servo s;

static void tick(void)
{
    hal.now_us += MOTION_TICK_US;
    servo_poll(&s);
}

static void start(void)
{
    hal_host_init(&hal);
    hal.now_us = 1000;
    servo_init(&s, &board_foot, &hal);
    s.regs.mem[REG_HEARTBEAT_ENABLE] = 0;
    uint8_t lim[2] = {0, 0}, sp[2] = {100, 0}, cur = 255;
    write_registers(&s, REG_CURRENT_LIMIT, &cur, 1);
    write_registers(&s, REG_CCW_LIMIT, lim, 2);
    write_registers(&s, REG_MOVING_SPEED, sp, 2);
    for (int i = 0; i < 500; i++)
        tick();
}

int main(void)
{
    static const char *const names[] = {"over-current", "under-voltage", "over-voltage",
                                        "over-temperature", "stall (jammed shaft)"};
    printf("== safety latencies (control ticks of 1 ms, foot in speed mode)\n");
    for (int f = 0; f < 5; f++) {
        start();
        if (f == 0) {
            uint8_t cur = 30;
            write_registers(&s, REG_CURRENT_LIMIT, &cur, 1);
            hal.current_extra_ma = 20000;
        } else if (f == 1) {
            hal.supply_mv = 6000;
        } else if (f == 2) {
            hal.supply_mv = 20000;
        } else if (f == 3) {
            hal.temperature_dc = 1000;
        } else {
            hal.motor.blocked = true;
        }
        unsigned detect = 0, off = 0;
        for (unsigned t = 1; t < 5000 && !off; t++) {
            tick();
            if (!detect && safety_err(&s.safety))
                detect = t;
            if (!off && hal.motor.duty == 0 && !hal.motor.enabled)
                off = t;
        }
        printf("%-22s detected after %4u ticks (filter), torque off %u ticks after detection\n",
               names[f], detect, off - detect);
    }
    start();
    s.regs.mem[REG_HEARTBEAT_ENABLE] = 1;
    s.safety.quiet_ticks = 0;
    unsigned stop = 0;
    for (unsigned t = 1; t < 2000 && !stop; t++) {
        tick();
        if (s.motion.mode != MOTION_SPEED)
            stop = t;
    }
    printf("heartbeat: expiry after %u ticks without a packet, stop begins %d ticks after expiry\n",
           SAFETY_HEARTBEAT_TICKS, (int)stop - (int)SAFETY_HEARTBEAT_TICKS);
    return 0;
}
