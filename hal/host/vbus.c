/* vbus.c - virtual bus: delivers each byte to every other device at its end time. */
#include <stdint.h>
#include <string.h>

#include "vbus.h"

void vbus_init(struct vbus *b)
{
    memset(b, 0, sizeof *b);
    b->now_us = HAL_HOST_CLOCK_START;
    b->step_us = 1;
    b->host_baud = 9600;
    b->wire_end_src = VBUS_HOST;
}

uint8_t vbus_add(struct vbus *b, const struct board *bd, uint8_t id)
{
    uint8_t i = b->nodes++;
    struct node *n = &b->node[i];
    bool configure = id && id != REGS_FACTORY_ID;
    node_init(n, bd, configure ? b->now_us - NODE_SET_ID_US : b->now_us);
    node_power_on(n);
    if (configure)
        (void)node_set_id(n, id);
    n->hal.now_us = b->now_us;
    return i;
}

void vbus_power_cycle(struct vbus *b, uint8_t i)
{
    struct node *n = &b->node[i];
    n->hal.now_us = b->now_us;
    node_restart(n);
}

const struct vbus_byte *vbus_wire(const struct vbus *b, uint32_t i)
{
    return &b->wire[i & (VBUS_WIRE_MAX - 1u)];
}

static void wire_put(struct vbus *b, int8_t src, uint8_t byte, uint32_t start, uint32_t end,
                     uint32_t baud)
{
    if (b->wire_len && src != b->wire_end_src && (int32_t)(start - b->wire_end_us) < 0)
        b->collisions++;
    struct vbus_byte *w = &b->wire[b->wire_len++ & (VBUS_WIRE_MAX - 1u)];
    w->start_us = start;
    w->end_us = end;
    w->baud = baud;
    w->byte = byte;
    w->src = src;
    if (b->wire_len == 1u || (int32_t)(end - b->wire_end_us) > 0) {
        b->wire_end_us = end;
        b->wire_end_src = src;
    }
}

/* Copy what the servos have started sending onto the wire (an answer is logged whole
 * when it starts), merged in time order. */
static void collect(struct vbus *b)
{
    struct node *nodes[VBUS_NODES_MAX];
    for (uint8_t i = 0; i < b->nodes; i++)
        nodes[i] = &b->node[i];
    int i;
    while ((i = node_tx_next(nodes, b->nodes, b->now_us + INT32_MAX)) >= 0) {
        const struct hal_tx_byte *t = node_tx_peek(nodes[i]);
        wire_put(b, (int8_t)i, t->byte, t->start_us, t->end_us, t->baud);
        node_tx_take(nodes[i]);
    }
}

/* Hand every byte that has ended by t to the devices that hear it. */
static void deliver(struct vbus *b, uint32_t t)
{
    while (b->delivered < b->wire_len) {
        const struct vbus_byte *w = vbus_wire(b, b->delivered);
        if ((int32_t)(w->end_us - t) > 0)
            break;
        for (uint8_t i = 0; i < b->nodes; i++) {
            struct node *n = &b->node[i];
            if (w->src == (int8_t)i || n->hal.baud != w->baud)
                continue; /* a UART does not hear itself, nor another baud rate */
            n->hal.now_us = w->end_us;
            servo_rx_isr(&n->servo, w->byte);
        }
        b->delivered++;
    }
}

void vbus_run_until(struct vbus *b, uint32_t t_us)
{
    while ((int32_t)(t_us - b->now_us) > 0) {
        uint32_t t = b->now_us + b->step_us;
        if ((int32_t)(t - t_us) > 0)
            t = t_us;
        deliver(b, t);
        b->now_us = t;
        for (uint8_t i = 0; i < b->nodes; i++)
            node_step(&b->node[i], t); /* a hal_restart() restarts it there */
        collect(b);
    }
}

uint32_t vbus_host_queue(struct vbus *b, const uint8_t *bytes, uint32_t n)
{
    if (n == 0)
        return b->now_us;
    uint32_t t0 = b->now_us;
    for (uint32_t i = 0; i < n; i++)
        wire_put(b, VBUS_HOST, bytes[i], hal_host_byte_start(t0, b->host_baud, i),
                 hal_host_byte_end(t0, b->host_baud, i), b->host_baud);
    b->last_host_end_us = hal_host_byte_end(t0, b->host_baud, n - 1u);
    return b->last_host_end_us;
}

void vbus_host_send(struct vbus *b, const uint8_t *bytes, uint32_t n)
{
    vbus_run_until(b, vbus_host_queue(b, bytes, n));
}

uint32_t vbus_host_pending(const struct vbus *b)
{
    uint32_t count = 0;
    for (uint32_t i = b->host_read; i < b->wire_len; i++)
        if (vbus_wire(b, i)->src != VBUS_HOST)
            count++;
    return count;
}

const struct vbus_byte *vbus_host_next(struct vbus *b)
{
    while (vbus_wire(b, b->host_read)->src == VBUS_HOST)
        b->host_read++;
    return vbus_wire(b, b->host_read++);
}
