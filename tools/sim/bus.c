/* bus.c - the servos of servo-sim in real time (bus.h). */
#include "bus.h"

#include <stdlib.h>
#include <time.h>

#include "sim.h"

#define BUS_CATCH_UP_US 200000u /* a servo this far behind real time jumps */
#define BUS_CONFIG_US 1000000u  /* virtual time reserved for configuring new servos */

static struct sim_servo *servos[SIM_SERVOS_MAX];
static struct node *nodes[SIM_SERVOS_MAX]; /* &servos[i]->node, for node_tx_next() */
static unsigned servo_count;
static struct timespec clock_zero;

uint32_t bus_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    int64_t us = ((int64_t)t.tv_sec - clock_zero.tv_sec) * 1000000 +
                 (t.tv_nsec - clock_zero.tv_nsec) / 1000;
    return (uint32_t)((uint64_t)us + BUS_CONFIG_US);
}

unsigned bus_count(void)
{
    return servo_count;
}

const struct sim_servo *bus_servo(unsigned i)
{
    return servos[i];
}

/* Run one servo's main loop at now; dispatch frames that wait while the link is free.
 * An answer that fell due since the last step is started at its due time first, as the
 * MCU's own clock would start it: a late start would slide one servo's broadcast-PING
 * slot into the next one's. */
static void run_at(struct sim_servo *v, uint32_t now)
{
    struct node *n = &v->node;
    uint32_t due = n->servo.link.due_us;
    if (n->servo.link.state == LINK_WAITING && (int32_t)(due - n->hal.now_us) > 0 &&
        (int32_t)(now - due) > 0)
        node_step(n, due);
    for (int i = 0; i < 8; i++) {
        node_step(n, now);
        const struct link *l = &n->servo.link;
        bool next_frame = l->state == LINK_IDLE && (frame_rx_peek(&n->servo.rx) ||
                                                    frame_rx_peek_block(&n->servo.rx));
        bool answer_due = l->state == LINK_WAITING && (int32_t)(now - l->due_us) >= 0;
        if (!next_frame && !answer_due)
            break; /* else go on at once: no answer waits for the next tick */
    }
}

/* Bring one servo up to now. On a loaded host this loop may wake late; the servo then
 * catches up in steps of BUS_TICK_US of its own clock, so its control loop still sees
 * the motor at its own pace (a jump would look like a stall or a current spike to the
 * firmware). Beyond BUS_CATCH_UP_US behind (the process was stopped) it jumps. */
static void step_one(struct sim_servo *v, uint32_t now)
{
    struct hal *h = &v->node.hal;
    if ((int32_t)(now - h->now_us) > (int32_t)BUS_CATCH_UP_US)
        h->now_us = now - BUS_CATCH_UP_US;
    while ((int32_t)(now - h->now_us) > (int32_t)BUS_TICK_US)
        run_at(v, h->now_us + BUS_TICK_US);
    run_at(v, now);
    state_sync(&v->state); /* also catches flash work done outside the wrapped calls */
}

void bus_step(uint32_t now)
{
    for (unsigned i = 0; i < servo_count; i++)
        step_one(servos[i], now);
}

static bool flash_blank(const struct hal *h)
{
    const uint8_t *m = &h->flash.mem[0][0];
    for (size_t i = 0; i < sizeof h->flash.mem; i++)
        if (m[i] != 0xFFu)
            return false;
    return true;
}

void bus_add(uint8_t arg_id, const struct board *b, const char *state_dir)
{
    struct sim_servo *v = calloc(1, sizeof *v);
    if (!v)
        die(1, "out of memory");
    v->arg_id = arg_id;
    nodes[servo_count] = &v->node;
    servos[servo_count++] = v;
    node_init(&v->node, b, 0); /* configuration runs from virtual time 0 */
    if (state_dir) /* before power-up: the store reads the flash there */
        state_open(&v->state, &v->node.hal, state_dir, arg_id, b->name);
    else
        state_none(&v->state, &v->node.hal);
    bool blank = flash_blank(&v->node.hal);
    node_power_on(&v->node); /* the factory image if the slot is blank, then the boot */
    state_write(&v->state);  /* a programmer's write is not a counted flash operation */
    if (blank && v->node.servo.link.id != arg_id && !node_set_id(&v->node, arg_id))
        die(1, "could not set the ID of servo %u:%s", arg_id, b->name);
    state_sync(&v->state);
}

void bus_start(void)
{
    clock_gettime(CLOCK_MONOTONIC, &clock_zero);
    uint32_t now = bus_now();
    for (unsigned i = 0; i < servo_count; i++)
        servos[i]->node.hal.now_us = now; /* the real clock starts after configuration */
}

void bus_host_bytes(const uint8_t *in, size_t n, uint32_t now)
{
    for (unsigned i = 0; i < servo_count; i++) {
        struct sim_servo *v = servos[i];
        step_one(v, now); /* bring the servo up to the arrival time */
        for (size_t k = 0; k < n; k++)
            servo_rx_isr(&v->node.servo, in[k]);
    }
}

size_t bus_output(uint32_t now, uint8_t *out, size_t max)
{
    size_t len = 0;
    for (;;) {
        int next = -1;
        uint32_t next_end = 0;
        for (unsigned i = 0; i < servo_count; i++) {
            const struct hal_tx_byte *t = node_tx_peek(nodes[i]);
            if (!t || (int32_t)(t->end_us - now) > 0)
                continue;
            if (next < 0 || (int32_t)(t->end_us - next_end) < 0) {
                next = (int)i;
                next_end = t->end_us;
            }
        }
        if (next < 0)
            return len;
        uint8_t byte = node_tx_peek(nodes[next])->byte;
        node_tx_take(nodes[next]);
        if (len < max)
            out[len++] = byte;
    }
}

uint32_t bus_next_wake(uint32_t now)
{
    uint32_t wake = BUS_TICK_US;
    for (unsigned i = 0; i < servo_count; i++) {
        const struct node *n = nodes[i];
        const struct hal_tx_byte *t = node_tx_peek(n);
        int32_t d;
        if (t) {
            d = (int32_t)(t->end_us - now);
            if (d <= 0)
                return 0; /* a byte is ready to go out */
            wake = (uint32_t)d < wake ? (uint32_t)d : wake;
        }
        if (n->servo.link.state == LINK_WAITING) {
            d = (int32_t)(n->servo.link.due_us - now);
            wake = d > 0 && (uint32_t)d < wake ? (uint32_t)d : wake;
        }
    }
    return wake;
}

void bus_free(void)
{
    for (unsigned i = 0; i < servo_count; i++) {
        state_close(&servos[i]->state);
        free(servos[i]);
    }
    servo_count = 0;
}
