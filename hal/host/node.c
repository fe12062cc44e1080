/* node.c - one servo on a host bus: power-on, main-loop pass, restart, ID, output. */
#include "node.h"

#include "proto.h"
#include "regs.h"

void node_init(struct node *n, const struct board *b, uint32_t now_us)
{
    hal_host_init(&n->hal);
    hal_host_attach_board(&n->hal, b); /* the motor and switches of this board */
    n->hal.now_us = now_us;
    n->board = b;
    n->log_seen = 0;
}

static bool app_slot_blank(const struct hal *h)
{
    const uint8_t *m = h->flash.mem[HAL_PAGE_APP];
    for (uint32_t i = 0; i < HAL_FLASH_PAGE_BYTES; i++)
        if (m[i] != 0xFFu)
            return false;
    return true;
}

void node_power_on(struct node *n)
{
    if (app_slot_blank(&n->hal))
        hal_host_program_factory(&n->hal, n->board);
    servo_power_on(&n->servo, n->board, &n->hal);
}

void node_restart(struct node *n)
{
    hal_host_reboot(&n->hal); /* the flash stays */
    servo_power_on(&n->servo, n->board, &n->hal);
}

void node_step(struct node *n, uint32_t now_us)
{
    n->hal.now_us = now_us;
    if (n->hal.stalled && (int32_t)(now_us - n->hal.stall_until_us) < 0)
        return; /* a flash erase holds the main loop (hal_host.h, erase_stall_us) */
    n->hal.stalled = false;
    servo_step(&n->servo);
    if (n->hal.restart_requested) /* hal_restart(): the MCU resets, the bootloader runs */
        node_restart(n);
}

bool node_set_id(struct node *n, uint8_t id)
{
    if (id > PROTO_ID_MAX)
        return false;
    uint8_t pkt[8];
    uint8_t params[2] = {REG_ID, id};
    uint16_t len = proto_build_packet(pkt, link_id(&n->servo.link), INS_WRITE, params, 2);
    for (uint16_t i = 0; i < len; i++)
        servo_rx_isr(&n->servo, pkt[i]);
    uint32_t t0 = n->hal.now_us;
    for (uint32_t t = 0; t <= NODE_SET_ID_US; t += 100u) {
        node_step(n, t0 + t);
        if (!loader_running(&n->servo.loader) && link_state(&n->servo.link) == LINK_IDLE && link_id(&n->servo.link) == id)
            break;
    }
    n->log_seen = n->hal.log_len; /* the answer went to nobody */
    return !loader_running(&n->servo.loader) && link_id(&n->servo.link) == id;
}

const struct hal_tx_byte *node_tx_peek(const struct node *n)
{
    return n->log_seen == n->hal.log_len ? 0 : hal_host_tx(&n->hal, n->log_seen);
}

void node_tx_take(struct node *n)
{
    if (n->log_seen != n->hal.log_len)
        n->log_seen++;
}

int node_tx_next(struct node *const *nodes, unsigned count, uint32_t until_us)
{
    int best = -1;
    uint32_t best_start = 0;
    for (unsigned i = 0; i < count; i++) {
        const struct hal_tx_byte *t = node_tx_peek(nodes[i]);
        if (!t || (int32_t)(t->start_us - until_us) > 0)
            continue;
        if (best < 0 || (int32_t)(t->start_us - best_start) < 0) {
            best = (int)i;
            best_start = t->start_us;
        }
    }
    return best;
}
