/* bench_motion.c - workload for `make bench`: control ticks and re-plans of the motion
 * layer, counted by callgrind (tools/bench.sh). It carries its own minimal HAL (an ideal
 * motor that follows the drive) so that only firmware instructions are counted.
 *
 *   bench_motion tick N     N control ticks of a long move (motion_poll, one tick each)
 *   bench_motion replan N   N goal changes mid-move (command_written)
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dispatch.h"
#include "command.h"
#include "write.h"
#include "hal.h"
#include "motion.h"
#include "servo.h"

struct hal {
    uint32_t now;
    int32_t pos;
    int16_t duty;
};

uint32_t hal_clock_us(struct hal *h) { return h->now; }
void hal_uart_set_baud(struct hal *h, uint32_t baud) { (void)h; (void)baud; }
uint32_t hal_uart_baud_achieved(const struct hal *h, uint32_t baud) { (void)h; return baud; }
void hal_uart_send(struct hal *h, const uint8_t *buf, uint16_t len) { (void)h; (void)buf; (void)len; }
bool hal_uart_tx_busy(struct hal *h) { (void)h; return false; }
uint32_t hal_irq_save(struct hal *h) { (void)h; return 0; }
void hal_irq_restore(struct hal *h, uint32_t state) { (void)h; (void)state; }
static uint8_t flash[HAL_PAGE_BOOTREC + 1u][HAL_FLASH_PAGE_BYTES];
const uint8_t *hal_flash_page(struct hal *h, uint8_t p) { (void)h; return flash[p]; }
bool hal_flash_erase(struct hal *h, uint8_t p) { (void)h; memset(flash[p], 0xFF, sizeof flash[p]); return true; }
bool hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t v)
{
    (void)h;
    flash[p][off] &= (uint8_t)v;
    flash[p][off + 1u] &= (uint8_t)(v >> 8);
    return true;
}
void hal_restart(struct hal *h) { (void)h; }
bool hal_reset_by_power(struct hal *h) { (void)h; return true; }
const uint8_t *hal_uid(struct hal *h) { static const uint8_t uid[HAL_UID_BYTES]; (void)h; return uid; }
void hal_motor_enable(struct hal *h, bool on) { (void)h; (void)on; }
void hal_motor_drive(struct hal *h, int16_t duty) { h->duty = duty; }
int32_t hal_motor_position(struct hal *h) { return h->pos += h->duty / 40; }
uint16_t hal_motor_current_ma(struct hal *h) { (void)h; return 100; }
uint16_t hal_supply_mv(struct hal *h) { (void)h; return 12000; }
int16_t hal_temperature_dc(struct hal *h) { (void)h; return 250; }
uint8_t hal_photo_switches(struct hal *h) { (void)h; return 0; }
void hal_rs485_termination(struct hal *h, bool on) { (void)h; (void)on; }
uint8_t hal_capabilities(struct hal *h) { (void)h; return 0xFFu; } /* every fitting */
void hal_watchdog_start(struct hal *h) { (void)h; }
void hal_watchdog_feed(struct hal *h) { (void)h; }

static struct hal hal;
static struct servo s;

static void write16(uint8_t addr, uint16_t v)
{
    uint8_t d[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    write_registers(&s, addr, d, 2);
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: bench_motion tick|replan N\n");
        return 2;
    }
    long n = strtol(argv[2], 0, 10);
    memset(flash, 0xFF, sizeof flash);
    servo_init(&s, &board_foot, &hal);
    s.regs.mem[REG_HEARTBEAT_ENABLE] = 0; /* no host talks here: the heartbeat would stop it */
    write16(REG_CW_LIMIT, 0);
    write16(REG_CCW_LIMIT, 30000);
    write16(REG_MOVING_SPEED, 90);
    write16(REG_GOAL_POSITION, 30000);
    if (strcmp(argv[1], "tick") == 0) {
        for (long i = 0; i < n; i++) {
            hal.now += MOTION_TICK_US;
            motion_poll(&s, hal.now);
        }
    } else {
        for (long i = 0; i < n; i++) {
            hal.now += MOTION_TICK_US;
            motion_poll(&s, hal.now);
            uint16_t g = (uint16_t)(i & 1 ? 20000 : 29000);
            const uint8_t d[2] = {(uint8_t)g, (uint8_t)(g >> 8)};
            const struct reg_write w = {REG_GOAL_POSITION, 2, s.regs.mem[REG_RESOLUTION], d,
                                       regs_mask(REG_GOAL_POSITION, 2)};
            regs_set(&s.regs, REG_GOAL_POSITION, g);
            command_written(&s, &w);
        }
    }
    printf("mode %u, reference at %lld counts\n", s.motion.mode,
           (long long)(s.motion.plan.pos >> PLANNER_SHIFT));
    return 0;
}
