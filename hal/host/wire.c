/* wire.c - the bus line at the bit level (wire.h). */
#include "wire.h"

#include <stdlib.h>
#include <string.h>

#define NONE INT64_MAX

void wire_init(struct wire *w, unsigned talkers)
{
    w->talkers = talkers;
    w->t = calloc(talkers ? talkers : 1u, sizeof *w->t);
    w->active = calloc(talkers ? talkers : 1u, sizeof *w->active);
    w->nactive = 0;
    w->changes = 0;
    if (!w->t || !w->active)
        abort();
}

void wire_free(struct wire *w)
{
    for (unsigned i = 0; i < w->talkers; i++)
        free(w->t[i].q);
    free(w->t);
    free(w->active);
    w->t = 0;
    w->active = 0;
    w->talkers = 0;
    w->nactive = 0;
}

int64_t wire_bit_ns(int64_t start_ns, uint32_t baud, unsigned k)
{
    return start_ns + ((int64_t)k * WIRE_NS_PER_S + baud - 1) / baud;
}

static const struct wire_byte *at(const struct wire_talker *tk, uint32_t i)
{
    return &tk->q[(tk->head + i) & (tk->cap - 1u)];
}

static int64_t byte_end(const struct wire_byte *b)
{
    return b->end_ns;
}

/* Keep the list of talkers with bytes on the line: only they can pull it low. */
static void update_active(struct wire *w, unsigned talker)
{
    bool has = w->t[talker].len > 0;
    for (unsigned k = 0; k < w->nactive; k++) {
        if (w->active[k] == talker) {
            if (!has)
                w->active[k] = w->active[--w->nactive];
            return;
        }
    }
    if (has)
        w->active[w->nactive++] = talker;
}

void wire_put(struct wire *w, unsigned talker, int64_t start_ns, uint32_t baud, uint8_t byte)
{
    struct wire_talker *tk = &w->t[talker];
    if (tk->len == 0)
        tk->head = 0;
    if (tk->len == tk->cap) {
        uint32_t cap = tk->cap ? tk->cap * 2u : 64u;
        struct wire_byte *q = malloc(cap * sizeof *q);
        if (!q)
            abort();
        for (uint32_t i = 0; i < tk->len; i++)
            q[i] = *at(tk, i);
        free(tk->q);
        tk->q = q;
        tk->cap = cap;
        tk->head = 0;
    }
    struct wire_byte *b = &tk->q[(tk->head + tk->len++) & (tk->cap - 1u)];
    b->start_ns = start_ns;
    b->end_ns = wire_bit_ns(start_ns, baud, 10);
    b->baud = baud;
    b->byte = byte;
    w->changes++;
    if (tk->len == 1u)
        update_active(w, talker);
}

int64_t wire_talker_end(const struct wire *w, unsigned talker)
{
    const struct wire_talker *tk = &w->t[talker];
    return tk->len ? byte_end(at(tk, tk->len - 1u)) : INT64_MIN;
}

void wire_drop_after(struct wire *w, unsigned talker, int64_t t)
{
    struct wire_talker *tk = &w->t[talker];
    while (tk->len && at(tk, tk->len - 1u)->start_ns > t) {
        tk->len--;
        w->changes++;
    }
    if (tk->len == 0)
        update_active(w, talker);
}

void wire_prune(struct wire *w, int64_t t)
{
    for (unsigned k = w->nactive; k-- > 0;) {
        unsigned i = w->active[k];
        struct wire_talker *tk = &w->t[i];
        while (tk->len && byte_end(at(tk, 0)) < t) {
            tk->head = (tk->head + 1u) & (tk->cap - 1u);
            tk->len--;
        }
        if (tk->len == 0)
            update_active(w, i);
    }
}

/* Index of the talker's last byte that starts at or before t, or -1. */
static int64_t last_at_or_before(const struct wire_talker *tk, int64_t t)
{
    int64_t lo = 0, hi = tk->len; /* the answer is lo - 1 once lo == hi */
    while (lo < hi) {
        int64_t mid = (lo + hi) / 2;
        if (at(tk, (uint32_t)mid)->start_ns <= t)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo - 1;
}

/* Bit k (0-9) of b: the start bit, the data bits LSB first, the stop bit. */
static int bit_of(const struct wire_byte *b, int64_t k)
{
    if (k <= 0)
        return 0;
    if (k >= 9)
        return 1;
    return (b->byte >> (k - 1)) & 1;
}

/* The talker's byte on the line at t (or 0), and which bit of it. */
static const struct wire_byte *byte_at(const struct wire_talker *tk, int64_t t, int64_t *bit)
{
    /* Most talkers of a large bus have nothing on the line at t (their answer is in
     * another slot): say so without the search. */
    if (tk->len == 0 || t < at(tk, 0)->start_ns || t >= at(tk, tk->len - 1u)->end_ns)
        return 0;
    int64_t i = last_at_or_before(tk, t);
    if (i < 0)
        return 0;
    const struct wire_byte *b = at(tk, (uint32_t)i);
    if (t >= byte_end(b))
        return 0;
    *bit = (t - b->start_ns) * (int64_t)b->baud / WIRE_NS_PER_S;
    return b;
}

bool wire_talker_busy(const struct wire *w, unsigned talker, int64_t t)
{
    int64_t bit;
    return byte_at(&w->t[talker], t, &bit) != 0;
}

int64_t wire_talker_free_at(const struct wire *w, unsigned talker, int64_t t)
{
    int64_t bit;
    const struct wire_byte *b = byte_at(&w->t[talker], t, &bit);
    return b ? byte_end(b) : t;
}

int wire_level(const struct wire *w, int64_t t)
{
    for (unsigned k = 0; k < w->nactive; k++) {
        int64_t bit;
        const struct wire_byte *b = byte_at(&w->t[w->active[k]], t, &bit);
        if (b && !bit_of(b, bit))
            return 0;
    }
    return 1;
}

/* Talker tk's level at t: 1 (idle, or a 1 bit) or 0. */
static int talker_level(const struct wire_talker *tk, int64_t t)
{
    int64_t bit;
    const struct wire_byte *b = byte_at(tk, t, &bit);
    return b ? bit_of(b, bit) : 1;
}

/* Talker tk is low at t: when it next goes high (the next 1 bit; the stop bit at the
 * latest). */
static int64_t talker_rise(const struct wire_talker *tk, int64_t t)
{
    int64_t bit;
    const struct wire_byte *b = byte_at(tk, t, &bit);
    int64_t k = bit + 1;
    while (k < 9 && !bit_of(b, k))
        k++;
    return wire_bit_ns(b->start_ns, b->baud, (unsigned)k);
}

/* Talker tk is high at t: when it next goes low (a 0 bit of its byte at t, or the start
 * of its next byte, which may begin a nanosecond before the previous one's rounded
 * end), or NONE. */
static int64_t talker_fall(const struct wire_talker *tk, int64_t t)
{
    int64_t next = NONE;
    if (tk->len == 0 || t >= at(tk, tk->len - 1u)->end_ns)
        return NONE;
    if (t < at(tk, 0)->start_ns)
        return at(tk, 0)->start_ns;
    int64_t bit, k = last_at_or_before(tk, t) + 1;
    const struct wire_byte *b = byte_at(tk, t, &bit);
    if (b) {
        for (int64_t j = bit + 1; j <= 8; j++) {
            if (!bit_of(b, j)) {
                next = wire_bit_ns(b->start_ns, b->baud, (unsigned)j);
                break;
            }
        }
    }
    if (k < (int64_t)tk->len && at(tk, (uint32_t)k)->start_ns < next)
        next = at(tk, (uint32_t)k)->start_ns;
    return next;
}

/* The first falling edge at or after t, or NONE. Not bit boundary by bit boundary (on
 * a bus of 253 servos whose answers overlap that is thousands per byte, each asking
 * every talker): while the line is low, on to the latest next rise of those pulling
 * it low (it cannot rise, nor so fall, before); once it is high, the earliest next fall
 * of anyone is the edge. */
static int64_t find_edge(const struct wire *w, int64_t t)
{
    while (t != NONE) {
        int low = 0;
        int64_t rise = t, fall = NONE;
        for (unsigned a = 0; a < w->nactive; a++) {
            const struct wire_talker *tk = &w->t[w->active[a]];
            if (!talker_level(tk, t)) {
                low = 1;
                int64_t r = talker_rise(tk, t);
                rise = r > rise ? r : rise;
            }
        }
        if (low) {
            if (wire_level(w, t - 1))
                return t; /* the line falls at t itself */
            t = rise;
            continue;
        }
        for (unsigned a = 0; a < w->nactive; a++) {
            int64_t f = talker_fall(&w->t[w->active[a]], t);
            fall = f < fall ? f : fall;
        }
        return fall;
    }
    return NONE;
}

/* For a receiver of every baud: the baud of the talker whose start bit begins at edge,
 * else of one that pulls the line low there. */
static uint32_t baud_at_edge(const struct wire *w, int64_t edge)
{
    uint32_t low = 0;
    for (unsigned k = 0; k < w->nactive; k++) {
        int64_t bit;
        const struct wire_byte *b = byte_at(&w->t[w->active[k]], edge, &bit);
        if (b && b->start_ns == edge)
            return b->baud;
        if (b && !bit_of(b, bit) && !low)
            low = b->baud;
    }
    return low ? low : 9600u;
}

/* Sample time of bit k (0 = start bit) of a byte whose falling edge is at edge. */
static int64_t sample_ns(int64_t edge, uint32_t baud, unsigned k)
{
    return edge + ((int64_t)(2u * k + 1u) * WIRE_NS_PER_S) / (2 * (int64_t)baud);
}

bool wire_rx_next(const struct wire *w, const struct wire_rx *r, struct wire_rx_byte *out)
{
    int64_t t = r->hunt_ns;
    for (;;) {
        int64_t edge = find_edge(w, t);
        if (edge == NONE)
            return false;
        uint32_t baud = r->baud ? r->baud : baud_at_edge(w, edge);
        int64_t s0 = sample_ns(edge, baud, 0);
        if (wire_level(w, s0) != 0) {
            t = s0; /* a glitch, not a start bit: hunt on */
            continue;
        }
        uint8_t byte = 0;
        for (unsigned k = 1; k <= 8; k++)
            byte = (uint8_t)(byte | (wire_level(w, sample_ns(edge, baud, k)) << (k - 1u)));
        out->edge_ns = edge;
        out->stop_ns = sample_ns(edge, baud, 9);
        out->end_ns = wire_bit_ns(edge, baud, 10);
        out->baud = baud;
        out->byte = byte;
        out->framing_ok = wire_level(w, out->stop_ns) == 1;
        return true;
    }
}

void wire_rx_take(struct wire_rx *r, const struct wire_rx_byte *b)
{
    r->hunt_ns = b->stop_ns;
}
