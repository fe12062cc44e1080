/* bus.c - the servos of servo-sim on one wire, in real time (bus.h). */
#include "bus.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "link.h"
#include "sim.h"

#define BUS_CONFIG_US 1000000 /* virtual time reserved for configuring new servos */
#define HOST_OUT_MAX 65536u   /* host bytes decoded between two bus_output() calls */
#define NONE INT64_MAX

static struct sim_servo *servos[SIM_SERVOS_MAX];
static unsigned servo_count;
static struct timespec clock_zero;

static struct wire wire; /* talkers: the servos by index, then the host */
static unsigned host_talker;

/* The host's side: its UART (baud 0: raw, hears every baud), whether one listens. */
static struct wire_rx host_rx;
static uint32_t host_baud;
static bool host_listening;
static uint8_t host_out[HOST_OUT_MAX];
static size_t host_out_len;

/* A raw client's bytes and their arrival times; each servo takes them at its own pace. */
static uint8_t raw_byte[BUS_RAW_MAX];
static int64_t raw_at_us[BUS_RAW_MAX];
static uint64_t raw_in; /* bytes a raw client has sent, ever */

static int64_t frontier_us; /* everything up to here has run */
static int64_t next_tick_us;

/* Each receiver's next byte, as decoded from the line when it last changed: receiver r
 * is servo r, or the host for r == servo_count. */
struct rx_next {
    bool valid, have;
    uint32_t changes, baud;
    struct wire_rx_byte b;
};
static struct rx_next rx_cache[SIM_SERVOS_MAX + 1u + BUS_EXT_MAX];

/* External UARTs on the line (bus_add_ext: a QEMU-run image's USART1 over TCP), after
 * the host among the talkers and receivers: receiver servo_count + 1 + e. */
struct ext {
    int fd;
    uint32_t baud;
    struct wire_rx rx;
    uint64_t raw_next;  /* the next raw client byte its UART takes */
    int64_t raw_end_ns;
    uint8_t out[BUS_EXT_OUT];
    size_t out_len;
};
static struct ext exts[BUS_EXT_MAX];
static unsigned ext_count;

static unsigned ext_talker(unsigned e)
{
    return servo_count + 1u + e;
}
static bool run_now[SIM_SERVOS_MAX];
static int64_t ran_us[SIM_SERVOS_MAX]; /* when each servo's main loop last ran */

int64_t bus_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return ((int64_t)t.tv_sec - clock_zero.tv_sec) * 1000000 +
           (t.tv_nsec - clock_zero.tv_nsec) / 1000 + BUS_CONFIG_US + HAL_HOST_CLOCK_START;
}

unsigned bus_count(void)
{
    return servo_count;
}

const struct sim_servo *bus_servo(unsigned i)
{
    return servos[i];
}

/* A servo's 32-bit clock reading as bus time (within 2^31 us of the frontier). */
static int64_t unwrap(uint32_t t)
{
    return frontier_us + (int32_t)(t - (uint32_t)frontier_us);
}

static int64_t ceil_us(int64_t ns)
{
    return (ns + 999) / 1000;
}

/* ---- Servos ---------------------------------------------------------------------- */

/* A hash of servo i and its count of answers (hal.sends, salt), so a run is
 * reproducible and two servos never draw alike for long. */
static uint32_t draw(unsigned i, uint32_t salt)
{
    uint32_t x = (i + 1u) * 0x9E3779B1u ^ (servos[i]->node.hal.sends + salt) * 0x85EBCA77u;
    x ^= x >> 15;
    x *= 0x2C1B3C6Du;
    x ^= x >> 12;
    return x;
}

/* How late servo i's pending answer starts after its due time, in whole microseconds
 * (its clock's unit): the main-loop latency and its receiver's sampling phase (1/16
 * bit), drawn per answer. collect() adds the part below a microsecond. */
static int64_t skew_us(unsigned i)
{
    return (int64_t)(draw(i, 1u) % (BUS_LOOP_US + 1u + 1000000u / servos[i]->node.hal.baud / 16u));
}

/* When servo i's pending answer starts, or NONE. */
static int64_t answer_start(unsigned i)
{
    const struct link *l = &servos[i]->node.servo.link;
    if (link_state(l) != LINK_WAITING)
        return NONE;
    return unwrap(link_due_us(l)) + skew_us(i);
}

/* Put what servo i started sending on the line, at its exact bit times: the HAL logs
 * whole microseconds, a transmission's bytes follow each other at the baud. */
static void collect(unsigned i)
{
    struct sim_servo *v = servos[i];
    const struct hal_tx_byte *t;
    while ((t = node_tx_peek(&v->node))) {
        uint32_t next_us = v->send_t0_us +
                           (uint32_t)((uint64_t)v->send_i * 10000000u / (v->send_baud ? v->send_baud : 1u));
        if (t->baud != v->send_baud || t->start_us != next_us) { /* a new transmission */
            v->send_t0_us = t->start_us;
            v->send_t0_ns = unwrap(t->start_us) * 1000 + draw(i, 0u) % 1000u;
            v->send_baud = t->baud;
            v->send_i = 0;
        }
        wire_put(&wire, i, wire_bit_ns(v->send_t0_ns, t->baud, 10u * v->send_i), t->baud, t->byte);
        v->send_i++;
        node_tx_take(&v->node);
    }
}

/* Register 20 in force (issue 25): a host sees each switch of a servo's terminator. */
static void report_terminator(struct sim_servo *v)
{
    bool on = v->node.hal.termination;
    if (on == v->terminator)
        return;
    v->terminator = on;
    fprintf(stderr, "servo-sim: ID %u terminator %s\n", link_id(&v->node.servo.link),
            on ? "on" : "off");
}

static bool commits_reported;

void bus_report_commits(void)
{
    commits_reported = true;
    for (unsigned i = 0; i < servo_count; i++)
        servos[i]->tokens = -1;
}

static void report_tokens(struct sim_servo *v)
{
    int now = store_tokens(&v->node.servo.store);
    if (!commits_reported || now == v->tokens)
        return;
    v->tokens = now;
    fprintf(stderr, "servo-sim: ID %u commit tokens %d\n", link_id(&v->node.servo.link), now);
}

static bool moves_reported;

void bus_report_moves(void)
{
    moves_reported = true;
    for (unsigned i = 0; i < servo_count; i++)
        servos[i]->moving = -1;
}

static void report_moving(struct sim_servo *v, int64_t t)
{
    int now = regs_get(&v->node.servo.regs, REG_MOVING);
    if (!moves_reported || now == v->moving)
        return;
    v->moving = now;
    fprintf(stderr, "servo-sim: ID %u moving %d at %lld us\n", link_id(&v->node.servo.link), now,
            (long long)t);
}

/* Run servo i's main loop at t: passes at once while a frame waits and the link is free,
 * or while its answer is due. Between its due time and its start (skew) the MCU is still
 * in the pass that will start it: nothing runs. */
static void run_at(unsigned i, int64_t t)
{
    struct node *n = &servos[i]->node;
    if (t < unwrap(n->hal.now_us))
        t = unwrap(n->hal.now_us); /* never back in time (a servo caught up late) */
    ran_us[i] = t;
    for (int pass = 0; pass < 8; pass++) {
        const struct link *l = &n->servo.link;
        if (link_state(l) == LINK_WAITING && t >= unwrap(link_due_us(l)) && t < answer_start(i))
            break;
        node_step(n, (uint32_t)t);
        collect(i);
        report_terminator(servos[i]);
        report_tokens(servos[i]);
        report_moving(servos[i], t);
        /* A frame is executed even while an answer waits (servo.c): only sending stops it. */
        bool next_frame = link_state(l) != LINK_SENDING && frame_rx_peek(&n->servo.rx) != NULL;
        if (!next_frame && !(link_state(l) == LINK_WAITING && t >= answer_start(i)))
            break; /* else go on at once: no answer waits for the next tick */
    }
    state_sync(&servos[i]->state); /* also catches flash work outside the wrapped calls */
}

static bool flash_blank(const struct hal *h)
{
    const uint8_t *m = &h->flash.mem[0][0];
    for (size_t i = 0; i < sizeof h->flash.mem; i++)
        if (m[i] != 0xFFu)
            return false;
    return true;
}

void bus_add(uint8_t arg_id, const struct board *b, const uint8_t uid[HAL_UID_BYTES],
             bool uid_names_file, const char *state_dir)
{
    struct sim_servo *v = calloc(1, sizeof *v);
    if (!v)
        die(1, "out of memory");
    v->arg_id = arg_id;
    servos[servo_count++] = v;
    node_init(&v->node, b, HAL_HOST_CLOCK_START); /* configuration runs before the real clock */
    memcpy(v->node.hal.uid, uid, HAL_UID_BYTES);
    if (state_dir) /* before power-up: the store reads the flash there */
        state_open(&v->state, &v->node.hal, state_dir, arg_id, b->name,
                   uid_names_file ? uid : NULL);
    else
        state_none(&v->state, &v->node.hal);
    bool blank = flash_blank(&v->node.hal);
    node_power_on(&v->node); /* the factory image if the slot is blank, then the boot */
    state_write(&v->state);  /* a programmer's write is not a counted flash operation */
    if (blank && link_id(&v->node.servo.link) != arg_id && !node_set_id(&v->node, arg_id))
        die(1, "could not set the ID of servo %u:%s", arg_id, b->name);
    report_terminator(v); /* register 20 from flash */
    state_sync(&v->state);
}

void bus_start(void)
{
    clock_gettime(CLOCK_MONOTONIC, &clock_zero);
    frontier_us = next_tick_us = bus_now();
    host_talker = servo_count;
    wire_init(&wire, servo_count + 1u + ext_count);
    for (unsigned e = 0; e < ext_count; e++)
        exts[e].rx.hunt_ns = frontier_us * 1000;
    for (unsigned i = 0; i < servo_count; i++) {
        ran_us[i] = frontier_us;
        servos[i]->node.hal.now_us = (uint32_t)frontier_us; /* the real clock starts */
        servos[i]->rx.hunt_ns = frontier_us * 1000;
    }
}

/* ---- Receivers ------------------------------------------------------------------- */

/* The last few decodes: receivers at one baud that took the same byte hunt from the
 * same point, and decode the same next byte (a bus of servos at one baud). */
#define MEMO 4u
static struct memo {
    bool used, have;
    uint32_t changes, baud;
    int64_t hunt_ns;
    struct wire_rx_byte b;
} memo[MEMO];
static unsigned memo_next;

static bool decode(const struct wire_rx *rx, struct wire_rx_byte *out)
{
    for (unsigned k = 0; k < MEMO; k++) {
        const struct memo *m = &memo[k];
        if (m->used && m->changes == wire.changes && m->baud == rx->baud &&
            m->hunt_ns == rx->hunt_ns) {
            *out = m->b;
            return m->have;
        }
    }
    struct memo *m = &memo[memo_next++ % MEMO];
    m->have = wire_rx_next(&wire, rx, &m->b);
    m->used = true;
    m->changes = wire.changes;
    m->baud = rx->baud;
    m->hunt_ns = rx->hunt_ns;
    *out = m->b;
    return m->have;
}

/* Receiver r's next byte on the line as it is now known, or 0. */
static const struct wire_rx_byte *rx_peek(unsigned r)
{
    bool host = r == servo_count;
    if (host && !host_listening)
        return 0;
    struct ext *x = r > servo_count ? &exts[r - servo_count - 1u] : 0;
    struct wire_rx *rx = x ? &x->rx : host ? &host_rx : &servos[r]->rx;
    uint32_t baud = x ? x->baud : host ? host_baud : servos[r]->node.hal.baud;
    struct rx_next *c = &rx_cache[r];
    if (!c->valid || c->changes != wire.changes || c->baud != baud) {
        rx->baud = baud;
        c->have = decode(rx, &c->b);
        c->valid = true;
        c->changes = wire.changes;
        c->baud = baud;
    }
    return c->have ? &c->b : 0;
}

static int64_t rx_due(unsigned r)
{
    const struct wire_rx_byte *b = rx_peek(r);
    return b ? ceil_us(b->end_ns) : NONE;
}

/* Receiver r completes its byte at t: a UART drops a framing error, and a byte that
 * ends while its own device is sending (its echo: uart.c drops it while tx_active). */
static void rx_deliver(unsigned r, int64_t t)
{
    const struct wire_rx_byte *b = rx_peek(r);
    bool host = r == servo_count;
    struct ext *x = r > servo_count ? &exts[r - servo_count - 1u] : 0;
    unsigned talker = x ? ext_talker(r - servo_count - 1u) : host ? host_talker : r;
    bool heard = b->framing_ok && !wire_talker_busy(&wire, talker, b->stop_ns);
    uint8_t byte = b->byte;
    wire_rx_take(x ? &x->rx : host ? &host_rx : &servos[r]->rx, b);
    rx_cache[r].valid = false;
    if (!heard)
        return;
    if (x) {
        if (x->out_len < sizeof x->out)
            x->out[x->out_len++] = byte;
        return;
    }
    if (host) {
        if (host_out_len < HOST_OUT_MAX)
            host_out[host_out_len++] = byte;
        return;
    }
    struct node *n = &servos[r]->node;
    if (t > unwrap(n->hal.now_us))
        n->hal.now_us = (uint32_t)t;
    servo_rx_isr(&n->servo, byte);
    /* A frame complete: the main loop takes it now (its answer is timed from it). Else
     * the next tick is soon enough, as a byte inside a frame asks nothing of it. */
    run_now[r] = frame_rx_peek(&n->servo.rx) != NULL;
}

/* When servo i's UART completes the next raw client byte (ns), or NONE: back to back
 * after the one before, not before it arrived, 10 bit-times at the servo's baud. */
static int64_t raw_end_ns(unsigned i)
{
    const struct sim_servo *v = servos[i];
    if (v->raw_next == raw_in)
        return NONE;
    int64_t start = raw_at_us[v->raw_next % BUS_RAW_MAX] * 1000;
    if (v->raw_end_ns > start)
        start = v->raw_end_ns;
    return wire_bit_ns(start, v->node.hal.baud, 10u);
}

static int64_t raw_due(unsigned i)
{
    int64_t end = raw_end_ns(i);
    return end == NONE ? NONE : ceil_us(end);
}

/* Servo i's UART completes raw client bytes up to t. */
static void raw_deliver(unsigned i, int64_t t)
{
    struct sim_servo *v = servos[i];
    struct node *n = &v->node;
    for (int64_t end; (end = raw_end_ns(i)) != NONE && ceil_us(end) <= t;) {
        if (ceil_us(end) > unwrap(n->hal.now_us))
            n->hal.now_us = (uint32_t)ceil_us(end);
        servo_rx_isr(&n->servo, raw_byte[v->raw_next++ % BUS_RAW_MAX]);
        v->raw_end_ns = end;
        run_now[i] = run_now[i] || frame_rx_peek(&n->servo.rx) != NULL;
    }
}

/* External UART e takes the raw client's bytes as servo i's does: paced at its baud. */
static int64_t ext_raw_end_ns(unsigned e)
{
    const struct ext *x = &exts[e];
    if (x->raw_next == raw_in)
        return NONE;
    int64_t start = raw_at_us[x->raw_next % BUS_RAW_MAX] * 1000;
    if (x->raw_end_ns > start)
        start = x->raw_end_ns;
    return wire_bit_ns(start, x->baud, 10u);
}

static void ext_raw_deliver(unsigned e, int64_t t)
{
    struct ext *x = &exts[e];
    for (int64_t end; (end = ext_raw_end_ns(e)) != NONE && ceil_us(end) <= t;) {
        if (x->out_len < sizeof x->out)
            x->out[x->out_len++] = raw_byte[x->raw_next % BUS_RAW_MAX];
        x->raw_next++;
        x->raw_end_ns = end;
    }
}

/* Frames servo i's receiver had to drop since the last report: say so on stderr, at
 * most one line per servo per BUS_DROPS_US of bus time (a storm would flood it). */
#define BUS_DROPS_US 100000
static void report_drops(unsigned i, int64_t t)
{
    struct sim_servo *v = servos[i];
    uint32_t now = frame_rx_dropped(&v->node.servo.rx);
    if (now == v->drops || t - v->drops_us < BUS_DROPS_US)
        return;
    fprintf(stderr, "servo-sim: ID %u dropped %u frame(s): no room in its receive queue "
            "(%u in all)\n", link_id(&v->node.servo.link), now - v->drops, now);
    v->drops = now;
    v->drops_us = t;
}

/* ---- Time ------------------------------------------------------------------------ */

/* When servo i's pending answer is to start, unless its main loop already ran at or
 * after that time: then something holds it (a frame arriving: listen before talk), and
 * its next tick or received byte runs it again. */
static int64_t answer_event(unsigned i)
{
    int64_t a = answer_start(i);
    return a > ran_us[i] ? a : NONE;
}

/* The earliest event: a main-loop tick, an answer's start, a receiver's byte. Each is
 * consumed when it runs (a tick moves on, a byte is taken, an answer starts or waits for
 * the next tick), so time always moves on. */
static int64_t next_event(void)
{
    int64_t t = next_tick_us;
    for (unsigned i = 0; i < servo_count; i++) {
        int64_t a = answer_event(i);
        t = a < t ? a : t;
    }
    for (unsigned r = 0; r <= servo_count + ext_count; r++) {
        int64_t d = rx_due(r);
        t = d < t ? d : t;
    }
    for (unsigned i = 0; i < servo_count; i++) {
        int64_t d = raw_due(i);
        t = d < t ? d : t;
    }
    for (unsigned e = 0; e < ext_count; e++) {
        int64_t d = ext_raw_end_ns(e);
        d = d == NONE ? NONE : ceil_us(d);
        t = d < t ? d : t;
    }
    return t;
}

static void prune(void)
{
    int64_t keep = frontier_us * 1000;
    for (unsigned r = 0; r <= servo_count + ext_count; r++) {
        if (r == servo_count && !host_listening)
            continue;
        int64_t h = r > servo_count ? exts[r - servo_count - 1u].rx.hunt_ns
                    : r == servo_count ? host_rx.hunt_ns : servos[r]->rx.hunt_ns;
        keep = h < keep ? h : keep;
    }
    wire_prune(&wire, keep - 1);
}

void bus_advance(int64_t now)
{
    if (now - frontier_us > BUS_CATCH_UP_US) /* the process was stopped: jump */
        frontier_us = next_tick_us = now - BUS_CATCH_UP_US;
    for (;;) {
        int64_t t = next_event();
        if (t > now)
            break;
        if (t < frontier_us)
            t = frontier_us;
        for (unsigned r = 0; r <= servo_count + ext_count; r++)
            if (rx_due(r) <= t)
                rx_deliver(r, t);
        for (unsigned i = 0; i < servo_count; i++)
            raw_deliver(i, t);
        for (unsigned e = 0; e < ext_count; e++)
            ext_raw_deliver(e, t);
        bool tick = t >= next_tick_us;
        for (unsigned i = 0; i < servo_count; i++) {
            if (tick || run_now[i] || answer_event(i) <= t)
                run_at(i, t);
            run_now[i] = false;
            report_drops(i, t);
        }
        while (next_tick_us <= t)
            next_tick_us += BUS_TICK_US;
        frontier_us = t;
    }
    frontier_us = now;
    prune();
}

/* Every drop not reported yet, now. */
static void report_all_drops(void)
{
    for (unsigned i = 0; i < servo_count; i++) {
        servos[i]->drops_us = INT64_MIN / 2;
        report_drops(i, frontier_us);
    }
}

uint32_t bus_next_wake(int64_t now)
{
    int64_t d = next_event() - now;
    return d <= 0 ? 0u : d > BUS_TICK_US ? BUS_TICK_US : (uint32_t)d;
}

/* ---- The host -------------------------------------------------------------------- */

/* The raw client's bytes not delivered yet are gone (it left, or a new one came). */
static void raw_forget(void)
{
    for (unsigned i = 0; i < servo_count; i++)
        servos[i]->raw_next = raw_in;
    for (unsigned e = 0; e < ext_count; e++)
        exts[e].raw_next = raw_in;
}

void bus_host_connect(int64_t now)
{
    bus_advance(now);
    raw_forget();
    /* The host's UART starts hunting once the bytes on the line now have ended. */
    int64_t t = now * 1000;
    for (unsigned k = 0; k < wire.talkers; k++) {
        int64_t free_at = wire_talker_free_at(&wire, k, now * 1000);
        t = free_at > t ? free_at : t;
    }
    host_rx.hunt_ns = t;
    host_rx.baud = 0;
    host_baud = 0;
    host_listening = true;
    host_out_len = 0;
    rx_cache[servo_count].valid = false;
    for (unsigned i = 0; i < servo_count; i++) {
        /* Line idle for the §1 gap: a frame in progress is abandoned. */
        struct node *n = &servos[i]->node;
        uint32_t idle = frame_rx_gap_us(n->hal.baud) + link_bytes_us(n->hal.baud, 1u) + 1u;
        (void)frame_rx_idle(&n->servo.rx, n->hal.now_us + idle);
    }
}

void bus_host_disconnect(int64_t now)
{
    bus_advance(now);
    raw_forget();
    wire_drop_after(&wire, host_talker, now * 1000);
    host_listening = false;
    host_baud = 0;
    host_out_len = 0;
}

void bus_host_uart(uint32_t baud)
{
    host_baud = baud;
}

size_t bus_host_raw_room(void)
{
    uint64_t oldest = raw_in;
    for (unsigned i = 0; i < servo_count; i++)
        oldest = servos[i]->raw_next < oldest ? servos[i]->raw_next : oldest;
    for (unsigned e = 0; e < ext_count; e++)
        oldest = exts[e].raw_next < oldest ? exts[e].raw_next : oldest;
    return BUS_RAW_MAX - (size_t)(raw_in - oldest);
}

void bus_host_raw(const uint8_t *in, size_t n, int64_t now)
{
    bus_advance(now);
    for (size_t k = 0; k < n; k++, raw_in++) {
        raw_byte[raw_in % BUS_RAW_MAX] = in[k];
        raw_at_us[raw_in % BUS_RAW_MAX] = now;
    }
}

void bus_host_send(const uint8_t *in, size_t n, int64_t now)
{
    bus_advance(now);
    int64_t t0 = now * 1000, end = wire_talker_end(&wire, host_talker);
    if (end > t0)
        t0 = end;
    for (size_t k = 0; k < n; k++)
        wire_put(&wire, host_talker, wire_bit_ns(t0, host_baud, 10u * (unsigned)k), host_baud, in[k]);
}

void bus_host_purge(int64_t now)
{
    wire_drop_after(&wire, host_talker, now * 1000);
}

size_t bus_output(uint8_t *out, size_t max)
{
    size_t n = host_out_len < max ? host_out_len : max;
    for (size_t i = 0; i < n; i++)
        out[i] = host_out[i];
    host_out_len = 0;
    return n;
}

void bus_add_ext(int fd, uint32_t baud)
{
    if (ext_count == BUS_EXT_MAX)
        die(2, "at most %u --uart", BUS_EXT_MAX);
    exts[ext_count++] = (struct ext){.fd = fd, .baud = baud};
}

unsigned bus_ext_count(void)
{
    return ext_count;
}

int bus_ext_fd(unsigned e)
{
    return exts[e].fd;
}

void bus_ext_send(unsigned e, const uint8_t *in, size_t n, int64_t now)
{
    bus_advance(now);
    struct ext *x = &exts[e];
    int64_t t0 = now * 1000, end = wire_talker_end(&wire, ext_talker(e));
    if (end > t0)
        t0 = end;
    for (size_t k = 0; k < n; k++)
        wire_put(&wire, ext_talker(e), wire_bit_ns(t0, x->baud, 10u * (unsigned)k), x->baud,
                 in[k]);
}

size_t bus_ext_output(unsigned e, uint8_t *out, size_t max)
{
    struct ext *x = &exts[e];
    size_t n = x->out_len < max ? x->out_len : max;
    memcpy(out, x->out, n);
    memmove(x->out, x->out + n, x->out_len - n);
    x->out_len -= n;
    return n;
}

void bus_free(void)
{
    report_all_drops();
    for (unsigned i = 0; i < servo_count; i++) {
        state_close(&servos[i]->state);
        free(servos[i]);
    }
    servo_count = 0;
    wire_free(&wire);
}
