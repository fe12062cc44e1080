/* test_durability.c - nothing acknowledged is lost (PROTOCOL.md §5.3, docs/persistence.md
 * "For host tools"), through the bus (vbus) and the simulated flash (flash_sim):
 * - the user sequence of issue 19, replayed exactly;
 * - long random seeded sequences on every variant: every stored EEPROM register and width,
 *   every high-byte change, background traffic to this and other IDs, REG WRITE + ACTION,
 *   SYNC WRITE, RESET, restarts and power cuts at random instants (also inside a flash
 *   operation). Properties checked against an independent model of the commit budget:
 *   a frame that changes no EEPROM value writes no flash record; every EEPROM write
 *   answered within the budget is in flash when the first byte of its answer leaves (and
 *   an unanswered one when the pass that dispatched it ends), so a cut at any later
 *   instant keeps it; when the budget defers a commit, each register keeps its old or its
 *   newest value.
 * DURABILITY_SEQUENCES (environment) sets the number of random sequences (long mode);
 * DURABILITY_SEED the first seed. A failure prints the seed that reproduces it. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "dispatch.h"
#include "ident.h"
#include "proto.h"
#include "store.h"
#include "vbus.h"
#include "test_rng.h"

static struct vbus bus;

/* Put an instruction packet on the wire; returns its length. */
static uint16_t send(uint8_t id, uint8_t ins, const uint8_t *data, uint8_t n)
{
    uint8_t pkt[260];
    uint16_t len = proto_build_packet(pkt, id, ins, data, n);
    vbus_host_send(&bus, pkt, len);
    return len;
}

/* Run until the bus has been quiet for quiet_us; collect what the servos sent. Returns
 * the number of bytes (copied to out, up to cap). */
static uint32_t settle(uint32_t quiet_us, uint8_t *out, uint32_t cap)
{
    uint32_t got = 0;
    uint32_t last = bus.now_us;
    while ((int32_t)(bus.now_us - last) < (int32_t)quiet_us) {
        vbus_run_until(&bus, bus.now_us + 500u);
        while (vbus_host_pending(&bus)) {
            uint8_t b = vbus_host_next(&bus)->byte;
            if (got < cap)
                out[got] = b;
            got++;
        }
        if ((int32_t)(bus.wire_end_us - last) > 0)
            last = bus.wire_end_us; /* quiet from the end of the last byte */
    }
    return got;
}

/* An instruction and its status packet: returns the ERR byte, or -1 if nothing came. */
static int transact(uint8_t id, uint8_t ins, const uint8_t *data, uint8_t n, uint8_t *params)
{
    send(id, ins, data, n);
    uint8_t ans[64];
    uint32_t len = settle(20000u, ans, sizeof ans);
    if (len == 0)
        return -1;
    assert_true(len >= 6u && len == ans[3] + 4u);
    assert_int_equal(ans[len - 1u], proto_sum(&ans[2], (uint16_t)(len - 3u)));
    if (params)
        memcpy(params, &ans[5], len - 6u);
    return ans[4];
}

/* Issue 19, as a new user met it on servo-sim: an arm at factory settings, CCW limit 200
 * (its high byte changes from 1 to 0), ~70 ordinary packets, then temperature limit 70
 * and ID 5, both answered; 2.5 s later the power is cut. Both must survive. */
static void issue19_commissioning_survives_a_cut(void **state)
{
    (void)state;
    vbus_init(&bus);
    bus.host_baud = board_arm.default_baud;
    bus.step_us = 50;
    vbus_add(&bus, &board_arm, 0);
    struct servo *s = &bus.node[0].servo;
    assert_int_equal(s->link.id, 1);
    assert_int_equal(regs_get(&s->regs, REG_CCW_LIMIT), 360); /* premise: high byte 1 */
    assert_int_equal(s->regs.mem[REG_TEMPERATURE_LIMIT], 80);

    /* 1. CCW angle limit 200: exactly the issue's bytes. */
    uint8_t pkt[16];
    const uint8_t ccw[] = {REG_CCW_LIMIT, 0xC8, 0x00};
    uint16_t len = proto_build_packet(pkt, 1, INS_WRITE, ccw, sizeof ccw);
    const uint8_t issue[] = {0xD5, 0x5D, 0x01, 0x05, 0x03, 0x08, 0xC8, 0x00, 0xD9};
    assert_int_equal(len, sizeof issue);
    assert_memory_equal(pkt, issue, sizeof issue);
    vbus_host_send(&bus, pkt, len);
    uint8_t ans[16];
    assert_int_equal(settle(20000u, ans, sizeof ans), 6);
    assert_int_equal(ans[4], 0);

    /* 2. Ordinary traffic: READs of its position and PINGs to another servo. */
    uint32_t flash_ops = bus.node[0].hal.flash.ops;
    for (int i = 0; i < 70; i++) {
        if (i % 2) {
            const uint8_t rd[] = {REG_TURNED_ANGLE, 2};
            assert_int_equal(transact(1, INS_READ, rd, sizeof rd, NULL), 0);
        } else {
            assert_int_equal(transact(2, INS_PING, NULL, 0, NULL), -1);
        }
    }
    uint32_t traffic_ops = bus.node[0].hal.flash.ops - flash_ops;

    /* 3. Temperature limit 70, then ID 5: both answered with ERR 0. */
    const uint8_t temp[] = {REG_TEMPERATURE_LIMIT, 70};
    assert_int_equal(transact(1, INS_WRITE, temp, sizeof temp, NULL), 0);
    const uint8_t id5[] = {REG_ID, 5};
    assert_int_equal(transact(1, INS_WRITE, id5, sizeof id5, NULL), 0);
    uint8_t v[2];
    const uint8_t rd_temp[] = {REG_TEMPERATURE_LIMIT, 1};
    assert_int_equal(transact(5, INS_READ, rd_temp, sizeof rd_temp, v), 0);
    assert_int_equal(v[0], 70);
    assert_int_equal(transact(5, INS_PING, NULL, 0, NULL), 1); /* §4.1: 03 01 ERR */

    /* 4. The power goes 2.5 s later. */
    vbus_run_until(&bus, bus.now_us + 2500000u);
    vbus_power_cycle(&bus, 0);
    vbus_run_until(&bus, bus.now_us + 10000u);
    if (transact(5, INS_PING, NULL, 0, NULL) != 1 || s->regs.mem[REG_TEMPERATURE_LIMIT] != 70)
        fail_msg("after the cut: ID %u, temperature limit %u, CCW limit %u (want 5, 70, 200); "
                 "the 70 packets of traffic wrote %u flash operations",
                 s->link.id, s->regs.mem[REG_TEMPERATURE_LIMIT],
                 regs_get(&s->regs, REG_CCW_LIMIT), traffic_ops);
    assert_int_equal(transact(1, INS_PING, NULL, 0, NULL), -1);
    assert_int_equal(transact(5, INS_READ, rd_temp, sizeof rd_temp, v), 0);
    assert_int_equal(v[0], 70);
    assert_int_equal(regs_get(&s->regs, REG_CCW_LIMIT), 200);
    assert_int_equal(traffic_ops, 0); /* §5.3: traffic that changes nothing writes nothing */
}

/* ---- Random sequences ------------------------------------------------------------ */

#define REFILL STORE_REFILL_US
#define GUARD_US 5000u /* keep model events this far from a refill instant */


static uint32_t rng;
static uint32_t rnd(void)
{
    return xorshift32(&rng);
}
static uint32_t below(uint32_t n) { return n ? rnd() % n : 0u; }

/* The test's own model of what the flash holds and of the commit budget
 * (docs/persistence.md, "For host tools"), independent of src/store.c. */
struct model {
    uint16_t flash[REGS_SIZE]; /* value per stored register a power-up would load */
    uint32_t tokens;
    uint32_t token_at;
    bool pending;              /* the table differs from flash: a commit waits */
    bool lazy;                 /* a change of an instruction without INS_COMMITS (CUSTOM
                                * MOVE's ramps on the base) waits for the next commit, or
                                * for the motor at rest with the budget full */
};

/* Figures over all sequences. */
struct tally {
    uint32_t sequences, frames, changing, answered_in_budget, unanswered_in_budget, deferred,
        deferred_landed, refused, cuts_between, cuts_mid_frame, cuts_in_flash, restarts, quiet_frames,
        lazy_changes, lazy_alone, lazy_along;
    uint32_t sent[256];     /* frames per instruction code */
    uint32_t sent_sub[256]; /* CUSTOM frames per sub-command */
    uint32_t hi_pairs[2][128][128 / 32]; /* CW, CCW: (old high byte, new high byte) seen */
};

static struct tally tally;
static struct model model;
static const struct board *bd;
static struct servo *sv;
static struct hal *hv;
static uint8_t cur_id;
static uint32_t seed_now;

static bool stored(uint8_t a)
{
    return regs_applicable(bd, a) && regs_table[a].area == REG_AREA_EE &&
           (regs_table[a].access & REG_ACCESS_W);
}

/* A property failed: say what, where, and the seed that replays it. a: the register, or
 * REGS_SIZE when want and got are counts. */
static void fail_seq(const char *what, uint8_t a, uint32_t want, uint32_t got)
{
    char where[32] = "count";
    if (a < REGS_SIZE)
        (void)snprintf(where, sizeof where, "register %u", a);
    fail_msg("seed %u (%s, frame %u, t=%u us): %s: %s is %u, want %u\n"
             "reproduce: DURABILITY_SEED=%u DURABILITY_SEQUENCES=1 test_durability",
             seed_now, bd->name, tally.frames, bus.now_us, what, where, got, want, seed_now);
}

/* What the flash holds now, as a power-up would load it (values written through the bus
 * are in range, so the table's rules change nothing). */
static void flash_values(uint16_t *out)
{
    static struct store_values v;
    static const struct hal *of;
    static uint32_t key = UINT32_MAX;
    uint32_t now_key = hv->flash.programs; /* the flash changes only by programs and erases */
    for (uint8_t p = 0; p < HAL_FLASH_PAGES; p++)
        now_key += hv->flash.erases[p] * 0x9E3779B1u;
    if (of != hv || key != now_key || !hv->flash.powered) { /* read it again */
        store_read(hv, &v);
        of = hv;
        key = now_key;
    }
    for (uint8_t a = 0; a < REGS_SIZE; a++)
        if (stored(a))
            out[a] = ((v.found >> a) & 1u) ? v.value[a] : regs_default(bd, a);
}

static void table_values(uint16_t *out)
{
    for (uint8_t a = 0; a < REGS_SIZE; a++)
        if (stored(a))
            out[a] = regs_get(&sv->regs, a);
}

static bool same(const uint16_t *x, const uint16_t *y)
{
    for (uint8_t a = 0; a < REGS_SIZE; a++)
        if (stored(a) && x[a] != y[a])
            return false;
    return true;
}

static void expect_flash(const uint16_t *want, const char *what)
{
    uint16_t got[REGS_SIZE];
    flash_values(got);
    for (uint8_t a = 0; a < REGS_SIZE; a++)
        if (stored(a) && got[a] != want[a])
            fail_seq(what, a, want[a], got[a]);
}

static void model_refill(uint32_t t)
{
    while (model.tokens < STORE_BURST && t - model.token_at >= REFILL) {
        model.tokens++;
        model.token_at += REFILL;
    }
    if (model.tokens == STORE_BURST)
        model.token_at = t;
}

/* A commit is due (the table changed at time t): within the budget it happens now. */
static bool model_commit(uint32_t t, const uint16_t *table)
{
    model_refill(t);
    if (model.tokens == 0u) {
        model.pending = true;
        return false;
    }
    model.pending = false;
    if (model.lazy)
        tally.lazy_along++; /* it goes with this commit */
    model.lazy = false;
    if (!same(table, model.flash)) {
        model.tokens--;
        memcpy(model.flash, table, sizeof model.flash);
    }
    return true;
}

static void model_power_up(void)
{
    model.tokens = STORE_BURST;
    model.token_at = bus.now_us;
    model.pending = false;
    model.lazy = false;
    flash_values(model.flash);
}

/* After one main-loop pass: a lazy change may have reached the flash on its own. It may
 * only while the budget is full (it must never spend what a host's settings rely on).
 * True if it did in this pass. */
static bool lazy_check(void)
{
    if (!model.lazy || model.pending)
        return false;
    uint16_t got[REGS_SIZE], table[REGS_SIZE];
    flash_values(got);
    if (same(got, model.flash))
        return false;
    table_values(table);
    if (!same(got, table))
        fail_seq("a lazy change reached flash with other values than the table's", REGS_SIZE, 0, 1);
    model_refill(bus.now_us);
    if (model.tokens != STORE_BURST)
        fail_seq("a lazy change spent the commit budget while it was not full", REGS_SIZE,
                 STORE_BURST, model.tokens);
    model.tokens--;
    model.token_at = bus.now_us;
    memcpy(model.flash, got, sizeof model.flash);
    model.lazy = false;
    tally.lazy_alone++;
    return true;
}

/* Run the bus to t: pass by pass while a lazy change may land, coarsely otherwise. */
static void run_to(uint32_t t)
{
    while (model.lazy && !model.pending && (int32_t)(t - bus.now_us) > 0) {
        vbus_run_until(&bus, bus.now_us + 500u);
        (void)lazy_check();
    }
    if ((int32_t)(t - bus.now_us) > 0)
        vbus_run_until(&bus, t);
}

/* The next instant the budget changes (a token arrives), or none. */
static bool next_refill(uint32_t *at)
{
    if (model.tokens >= STORE_BURST)
        return false;
    *at = model.token_at + REFILL;
    return true;
}

/* Run the bus idle until t (coarse steps: nothing is on the wire). A deferred commit
 * lands when its token arrives; the model follows at that instant. */
static void idle_until(uint32_t t)
{
    uint32_t step = bus.step_us;
    bus.step_us = 10000; /* the motor rests: coarse passes are enough */
    uint32_t r = 0;
    while ((model.pending || model.lazy) && next_refill(&r) && (int32_t)(r - t) <= 0) {
        if (model.lazy && !model.pending) { /* it lands once the bucket is full again */
            if (model.tokens + 1u < STORE_BURST) {
                vbus_run_until(&bus, r + GUARD_US);
                model_refill(bus.now_us);
                continue;
            }
            run_to(r + GUARD_US);
            break;
        }
        vbus_run_until(&bus, r + GUARD_US);
        uint16_t table[REGS_SIZE];
        table_values(table);
        model_refill(r);
        model.pending = false;
        if (!same(table, model.flash)) {
            model.tokens--;
            memcpy(model.flash, table, sizeof model.flash);
            tally.deferred_landed++;
        }
        expect_flash(model.flash, "a deferred commit did not land when its token came");
    }
    run_to(t);
    bus.step_us = step;
}

/* Keep the next frame's window clear of refill instants, so the model's and the
 * firmware's clocks can never disagree about the budget. */
static void clear_of_refill(uint32_t window)
{
    uint32_t r = 0;
    if (next_refill(&r) && (int32_t)(r - (bus.now_us + window + GUARD_US)) < 0 &&
        (int32_t)(r + GUARD_US - bus.now_us) > 0)
        idle_until(r + GUARD_US);
}

/* The host follows the servo's ID and baud; the main loop runs every half byte-time
 * (20-500 us): finer than anything on the wire. */
static void host_follow(void)
{
    cur_id = sv->regs.mem[REG_ID];
    bus.host_baud = link_baud(bd, sv->regs.mem[REG_BAUD_RATE]);
    uint32_t half = link_bytes_us(bus.host_baud, 1u) / 2u;
    bus.step_us = half < 20u ? 20u : half > 500u ? 500u : half;
}

/* The power goes and comes back: whatever was committed is what the servo loads. */
static void power_cycle(const char *why)
{
    vbus_power_cycle(&bus, 0);
    vbus_run_until(&bus, bus.now_us + 2u * bus.step_us);
    uint16_t table[REGS_SIZE];
    table_values(table);
    for (uint8_t a = 0; a < REGS_SIZE; a++)
        if (stored(a) && table[a] != model.flash[a])
            fail_seq(why, a, model.flash[a], table[a]);
    model_power_up();
    host_follow();
    /* What the servo had put on the wire before the cut ends there (the virtual UART
     * sends whole packets): the host waits for a quiet line. */
    if ((int32_t)(bus.wire_end_us - bus.now_us) > 0)
        vbus_run_until(&bus, bus.wire_end_us + frame_rx_gap_us(bus.host_baud));
    while (vbus_host_pending(&bus))
        (void)vbus_host_next(&bus);
}

/* A valid random value for stored register a (limits: within the other limit). */
static uint16_t random_value(uint8_t a, const uint16_t *table)
{
    const struct reg_desc *d = &regs_table[a];
    if (a == REG_CW_LIMIT || a == REG_CCW_LIMIT) {
        /* any high byte, so every high-byte change happens over the sequences */
        uint16_t v = (uint16_t)((below(128) << 8) | below(256));
        uint16_t cw = table[REG_CW_LIMIT], ccw = table[REG_CCW_LIMIT];
        if (a == REG_CW_LIMIT && v > ccw)
            v = (uint16_t)(below(4) ? below((uint32_t)ccw + 1u) : v); /* sometimes refused */
        if (a == REG_CCW_LIMIT && v < cw)
            v = (uint16_t)(below(4) ? cw + below(0x8000u - cw) : v);
        return v;
    }
    if (a == REG_RETURN_DELAY)
        return (uint16_t)(below(8) ? below(8) : below(256)); /* mostly short: a fast test */
    if (a == REG_BAUD_RATE)
        return (uint16_t)(below(3) ? 0u : 3u + below(8)); /* 38,400 baud and faster */
    if (a == REG_RESOLUTION)
        return (uint16_t)(below(2) ? 10u : 1u + below(255));
    if (a == REG_ID)
        return (uint16_t)below(PROTO_ID_MAX + 1u);
    return (uint16_t)(d->min + below((uint32_t)regs_max(d) - d->min + 1u));
}

/* A WRITE-style payload for a random span of stored registers: addr, then bytes. Now
 * and then a partial register or an unchanged value. */
static uint8_t random_ee_write(uint8_t *p, const uint16_t *table)
{
    uint8_t spans[REGS_SIZE], ns = 0;
    for (uint8_t a = 0; a < REGS_SIZE; a++)
        if (stored(a))
            spans[ns++] = a;
    uint8_t first = spans[below(ns)];
    uint8_t count = (uint8_t)(1u + (below(4) == 0 ? below(3) : 0u));
    p[0] = first;
    uint8_t n = 1;
    uint16_t t2[REGS_SIZE];
    memcpy(t2, table, sizeof t2);
    for (uint8_t a = first, k = 0; a < REGS_SIZE && k < count; k++) {
        if (!stored(a))
            break;
        uint16_t v = below(8) == 0 ? table[a] : random_value(a, t2);
        t2[a] = v;
        p[n++] = (uint8_t)v;
        if (regs_table[a].size == 2u)
            p[n++] = (uint8_t)(v >> 8);
        a = (uint8_t)(a + regs_table[a].size);
    }
    if (below(40) == 0) { /* a write that starts on a high byte: refused */
        p[0] = (uint8_t)(REG_CW_LIMIT + 1u);
        n = 2;
    }
    return n;
}

struct frame_plan {
    uint8_t id, ins, n;
    uint8_t data[64];
    bool for_us; /* may change this servo's table */
};

/* One frame of the sequence: an EEPROM change (WRITE, REG WRITE + ACTION, SYNC WRITE,
 * RESET, START/END, the base's CUSTOM MOVE ramps) or background traffic. */
static void plan_frame(struct frame_plan *f, const uint16_t *table, bool burst)
{
    uint8_t other = (uint8_t)((cur_id + 1u + below(20)) % (PROTO_ID_MAX + 1u));
    uint32_t k = below(burst ? 4u : 24u);
    f->for_us = true;
    f->id = cur_id;
    f->n = 0;
    if (k < 3u || (k < 8u && !burst)) {
        f->ins = INS_WRITE;
        f->n = random_ee_write(f->data, table);
        if (burst && f->data[0] == REG_BAUD_RATE)
            f->data[1] = 0; /* bursts keep the baud: many frames, quickly */
        return;
    }
    switch (k) {
    case 3: /* REG WRITE now, ACTION as the next frame */
        f->ins = INS_REG_WRITE;
        f->n = random_ee_write(f->data, table);
        return;
    case 8: /* SYNC WRITE of one register to this servo and another ID */
    {
        uint8_t w[8];
        uint8_t n = random_ee_write(w, table);
        uint8_t len = (uint8_t)(n - 1u);
        f->id = PROTO_ID_BROADCAST;
        f->ins = INS_SYNC_WRITE;
        f->data[0] = w[0];
        f->data[1] = len;
        uint8_t o = 2;
        f->data[o++] = other;
        for (uint8_t i = 0; i < len; i++)
            f->data[o++] = (uint8_t)below(256);
        f->data[o++] = cur_id;
        memcpy(&f->data[o], &w[1], len);
        f->n = (uint8_t)(o + len);
        return;
    }
    case 9:
        if (below(6) == 0) {
            f->ins = INS_RESET;
            return;
        }
        f->ins = INS_START_END;
        f->data[0] = (uint8_t)(1u + below(2));
        f->n = 1;
        return;
    case 10: /* CUSTOM MOVE with ramps: speed 0 (accepted) or, asleep, refused */
        f->ins = INS_CUSTOM;
        f->data[0] = 0x01;
        f->data[1] = (uint8_t)below(256);
        f->data[2] = 0;
        f->data[3] = below(2) ? 0u : 100u;
        f->data[4] = 0;
        f->data[5] = (uint8_t)below(256);
        f->data[6] = (uint8_t)below(256);
        f->n = 7;
        return;
    case 11: /* sleep on or off (RAM): a CUSTOM MOVE asleep is refused */
        f->ins = INS_WRITE;
        f->data[0] = REG_SLEEP;
        f->data[1] = (uint8_t)below(2);
        f->n = 2;
        return;
    case 12:
    case 13:
        f->ins = INS_READ;
        f->data[0] = (uint8_t)below(REGS_SIZE);
        f->data[1] = (uint8_t)(1u + below(REGS_SIZE - f->data[0]));
        f->n = 2;
        return;
    case 14:
        if (below(3) == 0) { /* the identity sub's SET ID (ident.h): its own UID or not */
            f->id = below(2) ? cur_id : PROTO_ID_BROADCAST;
            f->ins = INS_CUSTOM;
            f->data[0] = IDENT_SUB;
            f->data[1] = IDENT_SET_ID;
            memcpy(&f->data[2], hal_uid(hv), IDENT_UID_BYTES);
            f->data[2u + below(IDENT_UID_BYTES)] ^= below(4) == 0 ? 0x10u : 0u;
            f->data[14] = below(2) ? cur_id : (uint8_t)(1u + below(PROTO_ID_MAX));
            f->n = 15;
            return;
        }
        f->ins = INS_PING;
        return;
    default: /* traffic for other servos: PING, READ, WRITE of EEPROM registers */
        f->for_us = false;
        f->id = other;
        if (k % 3u == 0u) {
            f->ins = INS_PING;
        } else if (k % 3u == 1u) {
            f->ins = INS_READ;
            f->data[0] = REG_CW_LIMIT;
            f->data[1] = 4;
            f->n = 2;
        } else {
            f->ins = INS_WRITE;
            f->n = random_ee_write(f->data, table);
        }
        return;
    }
}

/* The instruction table's own word (dispatch.h): does this frame spend commits? CUSTOM's
 * rules are its sub-command's. */
static bool instruction_commits(const struct frame_plan *f)
{
    const struct instruction *t = dispatch_instructions;
    uint8_t count = dispatch_instruction_count, code = f->ins;
    if (f->ins == INS_CUSTOM && f->n > 0u) {
        t = dispatch_custom;
        count = dispatch_custom_count;
        code = f->data[0];
    }
    for (uint8_t i = 0; i < count; i++)
        if (t[i].code == code)
            return (t[i].flags & INS_COMMITS) != 0u;
    return false;
}

/* Send one frame and run the bus until it is quiet, checking the properties on the way.
 * cut: 0 none, 1 during reception, 2 at a random later instant, 3 inside a flash op. */
static void run_frame(const struct frame_plan *f, int cut)
{
    uint8_t pkt[80];
    uint16_t len = proto_build_packet(pkt, f->id, f->ins, f->data, f->n);
    uint16_t before[REGS_SIZE], table[REGS_SIZE];
    table_values(before);
    uint32_t level = sv->link.level, delay = sv->link.delay;
    uint32_t window = link_bytes_us(bus.host_baud, len + 60u) + delay * 500u + 40000u;
    clear_of_refill(window);
    tally.frames++;
    if (cut == 1) { /* the power goes while the frame arrives: it never happened */
        vbus_host_send(&bus, pkt, (uint32_t)(1u + below(len - 1u)));
        tally.cuts_mid_frame++;
        power_cycle("a cut during reception");
        return;
    }
    if (cut == 3) {
        hv->flash.cut_at = hv->flash.ops + 1u + below(20);
        hv->flash.cut_kind = (uint8_t)below(3);
    }
    uint32_t programs = hv->flash.programs, seq0 = sv->store.seq;
    uint32_t t_end = hal_host_byte_end(bus.now_us, bus.host_baud, len - 1u);
    /* Sent; the bus runs to the pass that dispatches it. Until its first byte has
     * arrived the line rests, so a lazy change may still land there, pass by pass. */
    uint32_t sent_end = vbus_host_queue(&bus, pkt, len);
    uint32_t first_byte = hal_host_byte_end(bus.now_us, bus.host_baud, 0u);
    while (model.lazy && !model.pending && (int32_t)(first_byte - bus.now_us) >= 0) {
        vbus_run_until(&bus, bus.now_us + bus.step_us);
        if (lazy_check())
            programs = hv->flash.programs;
    }
    vbus_run_until(&bus, sent_end);
    table_values(table);
    bool changed = !same(before, table);
    bool in_budget = false;
    if (!hv->flash.powered) { /* the cut hit this frame's commit: all or nothing */
        uint16_t got[REGS_SIZE];
        vbus_power_cycle(&bus, 0);
        vbus_run_until(&bus, bus.now_us + 2u * bus.step_us);
        table_values(got);
        if (!same(got, model.flash) && !same(got, table))
            fail_seq("a cut inside a commit kept neither the old nor the new image", REGS_SIZE,
                     0, 1);
        tally.cuts_in_flash++;
        model_power_up();
        host_follow();
        return;
    }
    hv->flash.cut_at = 0;
    tally.sent[f->ins]++;
    if (f->ins == INS_CUSTOM && f->n > 0u)
        tally.sent_sub[f->data[0]]++;
    bool commits = instruction_commits(f);
    if (!changed && commits && f->for_us && model.lazy && !model.pending) {
        /* An accepted write of an EEPROM register commits whatever differs from flash, a
         * waiting lazy change included, though it changed no value (unit.adversary): in
         * flash now, or deferred. A refused one does neither. */
        uint16_t got[REGS_SIZE];
        flash_values(got);
        changed = !same(got, model.flash) || sv->store.pending;
    }
    if (changed && !commits) { /* an instruction that does not spend the budget */
        tally.lazy_changes++;
        model.lazy = true;
        changed = false; /* nothing reaches flash now */
    } else if (changed) {
        tally.changing++;
        uint16_t was[REGS_SIZE];
        memcpy(was, model.flash, sizeof was);
        in_budget = model_commit(t_end, table);
        /* A commit appends exactly the registers whose value differs from flash, three
         * half-words each (a compaction writes the whole image instead). */
        uint32_t differ = 0, all = 0;
        for (uint8_t a = 0; a < REGS_SIZE; a++) {
            differ += stored(a) && was[a] != table[a];
            all += stored(a);
        }
        uint32_t wrote = hv->flash.programs - programs;
        bool compacted = sv->store.seq != seq0;
        if (in_budget && wrote != (compacted ? 6u + 3u * all : 3u * differ))
            fail_seq("a commit wrote other records than the changed registers", REGS_SIZE,
                     compacted ? 6u + 3u * all : 3u * differ, wrote);
        if (!in_budget)
            tally.deferred++;
        for (int w = 0; w < 2; w++) {
            uint8_t a = w ? REG_CCW_LIMIT : REG_CW_LIMIT;
            uint8_t o = (uint8_t)(before[a] >> 8), nw = (uint8_t)(table[a] >> 8);
            if (stored(a) && o != nw && o < 128u && nw < 128u)
                tally.hi_pairs[w][o][nw / 32u] |= 1u << (nw % 32u);
        }
    }
    /* Flash now: an unanswered write within the budget is in it already. */
    expect_flash(model.flash, changed ? (in_budget ? "a write within the budget is not in flash "
                                                     "at the end of its pass"
                                                   : "a deferred write reached flash early")
                                      : "flash changed for a frame that changed nothing");
    if (!changed && hv->flash.programs != programs)
        fail_seq("a frame that changed no EEPROM value wrote flash records", REGS_SIZE, 0,
                 hv->flash.programs - programs);
    /* Then pass by pass until quiet: the answer's first byte, a cut at a random instant. */
    uint32_t log0 = hv->log_len, quiet_from = bus.now_us, cut_at = 0;
    if (cut == 2)
        cut_at = bus.now_us + below(window);
    /* Pass by pass until the answer is due (no broadcast here is answered), then on to
     * 3 ms of quiet after the last byte. */
    uint32_t gap = frame_rx_gap_us(bus.host_baud); /* the servo never talks sooner */
    uint32_t due = t_end + (f->id == PROTO_ID_BROADCAST ? 0u : delay * 500u + gap) + 1000u;
    bool answered = false;
    uint8_t ans[8];
    uint32_t alen = 0;
    while ((int32_t)(bus.now_us - due) < 0 || (int32_t)(bus.now_us - quiet_from) < 3000) {
        uint32_t p0 = hv->flash.programs;
        bool fine = !answered && (int32_t)(bus.now_us - due) < 0;
        vbus_run_until(&bus, bus.now_us + (fine ? bus.step_us : 500u));
        if (lazy_check()) /* its records are the lazy change's, checked there */
            programs = hv->flash.programs;
        if (!answered && hv->log_len != log0) {
            answered = true;
            if (changed && in_budget) {
                /* Its first byte leaves in this pass: in flash already, no flash work now. */
                expect_flash(table, "an answered write within the budget is not in flash "
                                    "when its answer leaves");
                if (hv->flash.programs != p0)
                    fail_seq("flash was programmed in the pass that sent the answer", REGS_SIZE,
                             0, hv->flash.programs - p0);
                tally.answered_in_budget++;
            }
        }
        while (vbus_host_pending(&bus)) {
            uint8_t b = vbus_host_next(&bus)->byte;
            if (alen < sizeof ans)
                ans[alen++] = b;
        }
        if ((int32_t)(bus.wire_end_us - quiet_from) > 0)
            quiet_from = bus.wire_end_us; /* quiet from the end of the last byte */
        if (cut == 2 && (int32_t)(bus.now_us - cut_at) >= 0) {
            tally.cuts_mid_frame++;
            power_cycle("a cut after the frame lost a committed value");
            return;
        }
    }
    if (changed && in_budget && !answered)
        tally.unanswered_in_budget++;
    if (alen >= 5u && f->ins != INS_PING && (ans[4] & ERR_INSTRUCTION) && changed)
        fail_seq("a refused frame changed EEPROM values (§3.2: all or nothing)", REGS_SIZE, 0,
                 1);
    tally.refused += alen >= 5u && f->ins != INS_PING && (ans[4] & ERR_INSTRUCTION);
    if (!changed && hv->flash.programs != programs)
        fail_seq("a frame that changed no EEPROM value wrote flash records", REGS_SIZE, 0,
                 hv->flash.programs - programs);
    if (!answered && f->for_us && f->id != PROTO_ID_BROADCAST && level == 2u && f->n < 60u)
        tally.quiet_frames++; /* an error not reported, or a refused frame */
    expect_flash(model.flash, "flash differs from the model after the frame");
    host_follow();
}

static void one_sequence(uint32_t seed)
{
    seed_now = seed;
    rng = seed * 2654435761u + 0x9E3779B9u;
    if (rng == 0u)
        rng = 1;
    bd = board_all[seed % BOARD_COUNT];
    vbus_init(&bus);
    bus.host_baud = bd->default_baud;
    vbus_add(&bus, bd, 0);
    sv = &bus.node[0].servo;
    hv = &bus.node[0].hal;
    model_power_up();
    host_follow();
    bool burst = below(5) == 0; /* spend the whole budget, then wait for tokens */
    uint32_t frames = burst ? 130u + below(80) : 10u + below(40);
    bool reg_held = false;
    for (uint32_t i = 0; i < frames; i++) {
        uint16_t table[REGS_SIZE];
        table_values(table);
        struct frame_plan f;
        if (reg_held && below(2)) { /* ACTION, addressed or broadcast */
            f.ins = INS_ACTION;
            f.n = 0;
            f.id = below(2) ? cur_id : PROTO_ID_BROADCAST;
            f.for_us = true;
            reg_held = false;
        } else {
            plan_frame(&f, table, burst);
            if (f.ins == INS_REG_WRITE)
                reg_held = true;
        }
        uint32_t c = below(burst ? 400u : 40u);
        bool ee = f.ins == INS_WRITE || f.ins == INS_SYNC_WRITE || f.ins == INS_ACTION;
        run_frame(&f, c == 0 ? 1 : c == 1 ? 2 : (c < 5 && ee) ? 3 : 0);
        uint32_t e = below(burst ? 200u : 30u);
        if (e == 0) {
            tally.cuts_between++;
            idle_until(bus.now_us + below(burst ? 3000000u : 200000u));
            power_cycle("a cut between frames lost a committed value");
        } else if (e == 1) {
            tally.restarts++;
            power_cycle("a restart lost a committed value");
        } else if (e == 2 || (burst && e < 8)) {
            idle_until(bus.now_us + (burst ? below(2u * REFILL) : below(300000u)));
        }
    }
    /* The end: wait out any deferred commit (at most 64 s), then cut. A lazy change lands
     * once the bucket is full again (at most 64 x 64 s after a burst). */
    if (model.lazy && !model.pending) {
        for (uint32_t k = 0; k <= STORE_BURST && model.lazy; k++)
            idle_until(bus.now_us + REFILL); /* in steps: one difference spans < 35.8 min */
        if (model.lazy)
            fail_seq("a lazy change never reached flash with the motor at rest and the budget "
                     "full", REGS_SIZE, 0, 1);
    }
    if (model.pending) {
        uint32_t r = 0;
        assert_true(next_refill(&r));
        assert_true((int32_t)(r - bus.now_us) <= (int32_t)REFILL);
        idle_until(r + GUARD_US);
        assert_false(model.pending);
    }
    power_cycle("after the sequence a cut lost a committed value");
    tally.sequences++;
}

static uint32_t env_u32(const char *name, uint32_t dflt)
{
    const char *v = getenv(name);
    return v && *v ? (uint32_t)strtoul(v, NULL, 0) : dflt;
}

static void random_sequences_keep_every_acknowledged_write(void **state)
{
    (void)state;
    uint32_t n = env_u32("DURABILITY_SEQUENCES", 1000u);
    uint32_t seed0 = env_u32("DURABILITY_SEED", 1u);
    memset(&tally, 0, sizeof tally);
    for (uint32_t i = 0; i < n; i++) {
        one_sequence(seed0 + i);
        if (n > 1000u && (i + 1u) % 10000u == 0u)
            fprintf(stderr, "%u sequences clean (seeds %u-%u)\n", i + 1u, seed0, seed0 + i);
    }
    uint32_t pairs[2] = {0, 0};
    for (int w = 0; w < 2; w++)
        for (int o = 0; o < 128; o++)
            for (int x = 0; x < 4; x++)
                pairs[w] += (uint32_t)__builtin_popcount(tally.hi_pairs[w][o][x]);
    print_message("%u sequences (seeds %u-%u), %u frames, %u changed EEPROM values: %u answered "
                  "and %u unanswered within the budget, %u deferred (%u landed on a token), %u refused; "
                  "cuts: %u between frames, %u within a frame, %u inside a flash operation; "
                  "%u restarts; high-byte changes seen: CW %u, CCW %u of 16,256 pairs\n",
                  tally.sequences, seed0, seed0 + n - 1u, tally.frames, tally.changing,
                  tally.answered_in_budget, tally.unanswered_in_budget, tally.deferred,
                  tally.deferred_landed, tally.refused, tally.cuts_between, tally.cuts_mid_frame,
                  tally.cuts_in_flash, tally.restarts, pairs[0], pairs[1]);
    /* The premises: every kind of event happened, and every instruction the table says
     * spends commits was sent (a new one needs its generator here). */
    assert_true(tally.answered_in_budget > 0u && tally.unanswered_in_budget > 0u);
    for (uint8_t i = 0; i < dispatch_instruction_count; i++)
        if ((dispatch_instructions[i].flags & INS_COMMITS) && !tally.sent[dispatch_instructions[i].code])
            fail_msg("instruction 0x%02X spends commits (INS_COMMITS) but the generator never "
                     "sent it", dispatch_instructions[i].code);
    for (uint8_t i = 0; i < dispatch_custom_count; i++)
        if ((dispatch_custom[i].flags & INS_COMMITS) && !tally.sent_sub[dispatch_custom[i].code])
            fail_msg("CUSTOM sub 0x%02X spends commits (INS_COMMITS) but the generator never "
                     "sent it", dispatch_custom[i].code);
    print_message("lazy changes (CUSTOM MOVE's ramps on the base): %u, landed alone %u, with "
                  "another commit %u\n", tally.lazy_changes, tally.lazy_alone, tally.lazy_along);
    if (n >= 100u) {
        assert_true(tally.deferred > 0u && tally.deferred_landed > 0u);
        assert_true(tally.lazy_alone > 0u && tally.lazy_along > 0u);
        assert_true(tally.cuts_between && tally.cuts_mid_frame && tally.cuts_in_flash);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(issue19_commissioning_survives_a_cut),
        cmocka_unit_test(random_sequences_keep_every_acknowledged_write),
    };
    return cmocka_run_group_tests(tests, 0, 0);
}
