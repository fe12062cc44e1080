/* loader.c - update mode (loader.h) and the answer to a §10 frame, which the
 * application's dispatcher shares. */
#include <string.h>

#include "hal.h"
#include "loader.h"
#include "proto.h"
#include "servo.h"
#include "store.h"

uint8_t loader_update_frame(struct servo *s, const struct frame *f)
{
    struct link *l = &s->link;
    if (f->buf[0] != link_id(l))
        return UPDATE_GO_ON; /* §10 frames go to one ID; a broadcast is not for us */
    uint8_t ans[2], n;
    uint8_t out = update_frame(&s->update, s->hal, servo_board(s)->model_number, f->buf, f->len,
                               f->status == FRAME_OK, f->end_us, ans, &n);
    /* Always answered (whatever register 16 says), ERR 0, after the return delay. */
    link_answer(s, link_id(l), 0, ans, n, link_reply_at(l, f->end_us));
    if (out == UPDATE_RESTART)
        s->loader.restart_due = 1;
    return out;
}

/* The value the store holds for address a; false if it holds none. */
static bool stored_value(const struct store_values *v, uint8_t a, uint16_t *out)
{
    *out = v->value[a];
    return ((v->found >> a) & 1u) != 0u;
}

void loader_settings(struct hal *hal, const struct board *b, struct loader_settings *out)
{
    struct store_values v;
    uint16_t x;
    store_read(hal, &v);
    /* The table's ranges, which test_regs ties to these rules: ID 0..PROTO_ID_MAX, a
     * baud code link_baud() knows, any 8-bit delay. */
    out->id = stored_value(&v, REG_ID, &x) && x <= PROTO_ID_MAX ? (uint8_t)x : REGS_FACTORY_ID;
    out->baud_code = stored_value(&v, REG_BAUD_RATE, &x) && x <= 0xFFu &&
                             link_baud(b, (uint8_t)x) != 0u
                         ? (uint8_t)x
                         : 0u;
    out->delay = stored_value(&v, REG_RETURN_DELAY, &x) && x <= 0xFFu ? (uint8_t)x
                                                                       : b->return_delay;
}

void loader_init(struct servo *s, const struct board *b, struct hal *hal)
{
    struct loader_settings set;
    memset(s, 0, sizeof *s);
    s->hal = hal;
    s->board = b;
    s->loader.running = 1;
    loader_settings(hal, b, &set);
    regs_put8(&s->regs, REG_ID, set.id);
    regs_put8(&s->regs, REG_BAUD_RATE, set.baud_code);
    regs_put8(&s->regs, REG_RETURN_DELAY, set.delay);
    frame_rx_init(&s->rx, link_baud(b, set.baud_code));
    link_latch(s);
}
