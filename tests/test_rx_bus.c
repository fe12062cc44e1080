/* test_rx_bus.c - the receive path as a host meets it (issue 25): servos on the virtual
 * bus (vbus.h), a host that sends the way hosts do, and the verdict from what a host
 * sees: the control table a READ returns, and the answers. The servos' own receivers are
 * looked at for two things only, both through the host model (struct node): the frames
 * each one dispatched (to tell a frame that passed an 8-bit checksum by chance from a
 * lost one), and its count of frames dropped for want of room (frame_rx.h, overruns).
 *
 * First the regressions of issue 25, with the issue's two examples verbatim; then the
 * property "a lost byte costs one packet, whatever the bytes around it". */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "proto.h"
#include "regs.h"
#include "vbus.h"
#include "test_rng.h"

#define FAST_CODE 10u     /* register 4: 1792000 baud (§5.2) */
#define FAST_BAUD 1792000u
#define ANSWER_US 20000u  /* no answer this long after the §1 time-out: none comes */
#define TRACE_MAX 96u

static struct vbus bus;
static uint32_t most_records; /* records a receiver had in use at once, at most */
static uint32_t dispatched[VBUS_NODES_MAX]; /* good frames each servo's main loop took */

/* The good frames each servo's receiver handed to its main loop, header stripped. */
static struct trace {
    uint32_t n;
    uint16_t len[TRACE_MAX];
    uint8_t b[TRACE_MAX][FRAME_BYTES];
} trace[VBUS_NODES_MAX];

/* Status packets the host heard (header included), and its parser's state. */
#define HEARD_MAX 64u
static struct {
    uint32_t n;
    uint8_t len[HEARD_MAX];
    uint8_t b[HEARD_MAX][PROTO_STATUS_MAX];
    uint8_t cur[PROTO_STATUS_MAX];
    uint32_t have;
} heard;

/* ---- the bus, stepped one main-loop period at a time -------------------------------- */

static void step(void)
{
    uint8_t tail[VBUS_NODES_MAX];
    for (uint8_t k = 0; k < bus.nodes; k++)
        tail[k] = bus.node[k].servo.rx.rec_tail;
    vbus_run_until(&bus, bus.now_us + bus.step_us);
    for (uint8_t k = 0; k < bus.nodes; k++) {
        const struct frame_rx *rx = &bus.node[k].servo.rx;
        uint32_t used = (uint8_t)(rx->rec_end - rx->rec_tail);
        most_records = used > most_records ? used : most_records;
        if (rx->rec_tail == tail[k] || rx->view.status != FRAME_OK || rx->view.len > FRAME_BYTES)
            continue; /* nothing dispatched, a bad checksum, a §10 data block */
        dispatched[k]++;
        struct trace *t = &trace[k];
        if (t->n == TRACE_MAX)
            continue; /* the property's rounds stay well under it */
        t->len[t->n] = rx->view.len;
        memcpy(t->b[t->n], rx->view.buf, rx->view.len);
        t->n++;
    }
    /* The host's receiver: the servos' bytes whose stop bit is over, as status packets
     * (a servo's answer is on the wire log whole from its start). */
    for (; bus.host_read < bus.wire_len; bus.host_read++) {
        const struct vbus_byte *w = vbus_wire(&bus, bus.host_read);
        if (w->src == VBUS_HOST)
            continue;
        if ((int32_t)(w->end_us - bus.now_us) > 0)
            break;
        uint8_t c = w->byte;
        if (heard.have == 0u && c != PROTO_HEADER0)
            continue;
        if (heard.have == 1u && c != PROTO_HEADER1) {
            heard.have = c == PROTO_HEADER0;
            continue;
        }
        heard.cur[heard.have++] = c;
        if (heard.have >= 4u && heard.have == 4u + heard.cur[3]) {
            assert_true(heard.n < HEARD_MAX);
            if (heard.cur[3] >= 2u && proto_sum(&heard.cur[2], (uint16_t)(heard.have - 3u)) ==
                                          heard.cur[heard.have - 1u]) {
                heard.len[heard.n] = (uint8_t)heard.have;
                memcpy(heard.b[heard.n++], heard.cur, heard.have);
            }
            heard.have = 0;
        } else if (heard.have == sizeof heard.cur) {
            heard.have = 0;
        }
    }
}

static void run_until(uint32_t t)
{
    while ((int32_t)(t - bus.now_us) > 0)
        step();
}

static void run_ms(uint32_t ms)
{
    run_until(bus.now_us + ms * 1000u);
}

/* Index of the first status packet from id heard since `from`, or -1. */
static int heard_from(uint8_t id, uint32_t from)
{
    for (uint32_t i = from; i < heard.n; i++)
        if (heard.b[i][2] == id)
            return (int)i;
    return -1;
}

/* Put bytes on the wire back to back and run until the last has ended. */
static void send(const uint8_t *b, uint32_t n)
{
    run_until(vbus_host_queue(&bus, b, n));
}

/* How long a host waits for an answer: a broken frame the request ended up inside holds
 * it until the line has rested for the §1 time-out. */
static uint32_t answer_wait_us(void)
{
    return frame_rx_gap_us(bus.host_baud) + ANSWER_US;
}

/* Send one instruction to id and wait for its answer; the answer's index in heard, or -1
 * if none came within answer_wait_us(). */
static int ask(uint8_t id, uint8_t ins, const uint8_t *par, uint8_t n)
{
    uint8_t pkt[260];
    uint16_t len = proto_build_packet(pkt, id, ins, par, n);
    heard.n = 0; /* what was heard before is the caller's past */
    uint32_t from = heard.n;
    send(pkt, len);
    uint32_t deadline = bus.now_us + answer_wait_us();
    int a;
    while ((a = heard_from(id, from)) < 0 && (int32_t)(deadline - bus.now_us) > 0)
        step();
    return a;
}

static void write8(uint8_t id, uint8_t addr, uint8_t v)
{
    uint8_t p[2] = {addr, v};
    int a = ask(id, INS_WRITE, p, 2);
    assert_true(a >= 0);
    assert_int_equal(heard.b[a][4], 0); /* ERR */
}

/* READ of n bytes at addr from id into out. */
static void read_regs(uint8_t id, uint8_t addr, uint8_t n, uint8_t *out)
{
    uint8_t p[2] = {addr, n};
    int a = ask(id, INS_READ, p, 2);
    if (a < 0)
        fail_msg("no answer from ID %u to READ %u..%u", id, addr, addr + n - 1u);
    assert_int_equal(heard.b[a][3], n + 2u);
    memcpy(out, &heard.b[a][5], n);
}

static uint16_t read16(uint8_t id, uint8_t addr)
{
    uint8_t v[2];
    read_regs(id, addr, 2, v);
    return (uint16_t)(v[0] | v[1] << 8);
}

/* Fresh servos of the given boards and IDs on an empty bus, each switched (through the
 * bus, as a host would) to a return delay of two byte-times (so that a stray byte the
 * host sends right after its request is over before the answer starts), checksum errors
 * not answered (register 18 bit 4, see property_run()) and baud code `code`, the host
 * then at `baud`. used_store: each servo's store pages hold old data (programmed, not
 * erased: every page of its rotation must be erased before it is written). */
static void open_bus_on(const struct board *const *b, const uint8_t *id, uint8_t count,
                        uint8_t code, uint32_t baud, bool used_store)
{
    /* Two byte-times at the new baud, in units of 500 us: at least 1. */
    uint8_t delay = (uint8_t)((20000000u / baud + 499u) / 500u);
    vbus_init(&bus);
    bus.step_us = 10; /* main-loop passes: an MCU's loop spins far faster than a frame */
    bus.host_baud = b[0]->default_baud;
    memset(trace, 0, sizeof trace);
    memset(&heard, 0, sizeof heard);
    for (uint8_t k = 0; k < count; k++) {
        assert_int_equal(b[k]->default_baud, bus.host_baud);
        assert_int_equal(vbus_add(&bus, b[k], id[k]), k);
        if (used_store) {
            memset(bus.node[k].hal.flash.mem, 0x00, HAL_FLASH_PAGES * HAL_FLASH_PAGE_BYTES);
            vbus_power_cycle(&bus, k); /* its ID is gone with the store: the factory's */
            assert_int_equal(id[k], REGS_FACTORY_ID);
        }
    }
    run_ms(5);
    for (uint8_t k = 0; k < count; k++) {
        write8(id[k], REG_RETURN_DELAY, delay);
        write8(id[k], REG_UNLOAD_CONDITIONS, 0x7Fu & ~UNLOAD_REPORT_CHECKSUM);
        write8(id[k], REG_BAUD_RATE, code);
        run_ms(2); /* the answer went out at the old baud; the new one applies */
    }
    bus.host_baud = baud;
    for (uint8_t k = 0; k < count; k++) {
        int a = ask(id[k], INS_PING, NULL, 0);
        assert_true(a >= 0);
    }
}

static void open_bus(const struct board *const *b, const uint8_t *id, uint8_t count,
                     uint8_t code, uint32_t baud)
{
    open_bus_on(b, id, count, code, baud, false);
}

static void assert_nothing_dropped(void)
{
    for (uint8_t k = 0; k < bus.nodes; k++)
        assert_int_equal(bus.node[k].servo.rx.overruns, 0);
    assert_int_equal(bus.collisions, 0);
}

/* ---- the regressions of issue 25 ------------------------------------------------------ */

/* "A SYNC WRITE D5 5D FE 07 83 1E 02 09 D5 5D E3 loses its ID byte, and the WRITE speed 0
 * right after it is never executed; a foot turning in speed mode keeps turning."
 * Here a base, which turns in speed mode from the factory; the heartbeat is off, so
 * only the WRITE can stop it. */
static void issue25_sync_write_without_its_id_keeps_the_write_behind_it(void **state)
{
    (void)state;
    const struct board *b[] = {&board_base};
    const uint8_t id[] = {1};
    open_bus(b, id, 1, FAST_CODE, FAST_BAUD);
    write8(1, REG_HEARTBEAT_ENABLE, 0);
    uint8_t turn[3] = {REG_MOVING_SPEED, 0x68, 0x01}; /* 360 */
    assert_true(ask(1, INS_WRITE, turn, 3) >= 0);
    run_ms(1500); /* up to speed: the base's ramp is 360 deg/s^2 */
    assert_int_equal(read16(1, REG_MOVING_SPEED), 360);
    assert_true((int16_t)read16(1, REG_PRESENT_SPEED) > 300);

    const uint8_t sync[] = {0xD5, 0x5D, 0xFE, 0x07, 0x83, 0x1E, 0x02, 0x09, 0xD5, 0x5D, 0xE3};
    assert_int_equal(sync[10], proto_sum(&sync[2], 8));
    uint8_t wire[64];
    uint32_t n = 0;
    for (uint32_t i = 0; i < sizeof sync; i++)
        if (i != 2u) /* FE lost on the wire */
            wire[n++] = sync[i];
    const uint8_t stop[] = {REG_MOVING_SPEED, 0, 0};
    n += proto_build_packet(&wire[n], PROTO_ID_BROADCAST, INS_WRITE, stop, sizeof stop);
    send(wire, n);
    run_ms(10);
    assert_int_equal(read16(1, REG_MOVING_SPEED), 0); /* executed (late, not lost) */
    run_ms(2000);
    assert_int_equal((int16_t)read16(1, REG_PRESENT_SPEED), 0);
    uint8_t moving;
    read_regs(1, REG_MOVING, 1, &moving);
    assert_int_equal(moving, 0);
    assert_nothing_dropped();
}

/* "Junk holding two nested headers (D5 5D D5 5D 01 FF) swallows the next three good
 * packets": here three broadcast WRITEs right behind it, each of its own register. */
static void issue25_junk_with_nested_headers_keeps_the_next_three_packets(void **state)
{
    (void)state;
    const struct board *b[] = {&board_foot};
    const uint8_t id[] = {1};
    open_bus(b, id, 1, FAST_CODE, FAST_BAUD);
    const uint8_t junk[] = {0xD5, 0x5D, 0xD5, 0x5D, 0x01, 0xFF};
    const uint8_t w[3][3] = {{REG_MOVING_SPEED, 0xD5, 0x5D}, {REG_ACCELERATION, 0x5D, 0},
                             {REG_DECELERATION, 0xD5, 0}};
    uint8_t wire[64];
    uint32_t n = sizeof junk;
    memcpy(wire, junk, n);
    for (uint32_t i = 0; i < 3; i++)
        n += proto_build_packet(&wire[n], PROTO_ID_BROADCAST, INS_WRITE, w[i],
                                i == 0 ? 3u : 2u);
    send(wire, n);
    run_ms(5); /* the junk's "frames" end at the line's §1 time-out */
    uint8_t t[4];
    read_regs(1, REG_MOVING_SPEED, 4, t);
    assert_int_equal(t[0] | t[1] << 8, 0x5DD5);
    assert_int_equal(t[2], 0x5D);
    assert_int_equal(t[3], 0xD5);
    assert_nothing_dropped();
}

/* ---- the property: a lost byte costs one packet, whatever the bytes around it -------- */

/* Six servos, two of whose IDs are the header bytes themselves (a SYNC WRITE slice for
 * them reads 5D v v, D5 v v), each with three cells a packet may write: the moving speed,
 * the acceleration and the deceleration, RAM registers that start nothing on a joint at
 * rest in position mode. A packet writes only cells no other packet of its round writes,
 * each with a value the cell does not hold: a lost packet shows in the table. */
#define NS 6u
#define CELLS 3u
#define ROUND_MAX 40u
static const struct board *const prop_board[NS] = {&board_foot,  &board_arm,  &board_wrist,
                                                   &board_finger, &board_foot, &board_arm};
static const uint8_t prop_id[NS] = {0x01, 0x5D, 0xD5, 0x02, 0xD4, 0x5C};
static const uint8_t cell_addr[CELLS] = {REG_MOVING_SPEED, REG_ACCELERATION, REG_DECELERATION};
/* Register ranges a WRITE or SYNC WRITE covers: first cell, cells. */
static const uint8_t range_first[5] = {0, 1, 2, 1, 0}, range_cells[5] = {1, 1, 1, 2, 3};

struct pkt {
    uint8_t b[96]; /* D5 5D ... CHK */
    uint8_t n;
    uint8_t to;     /* an ID, or broadcast */
    uint8_t ins;
    bool ends_burst; /* addressed: the host waits for its answer or its time-out */
    int32_t eff[NS][CELLS]; /* the value it writes, or -1 */
};

static uint32_t rng = 0x2545F491u;
static uint32_t rnd(void)
{
    return xorshift32(&rng);
}

/* A byte that is D5 or 5D half of the time. */
static uint8_t rich(void)
{
    uint32_t r = rnd() % 4u;
    return r == 0 ? 0xD5u : r == 1 ? 0x5Du : (uint8_t)rnd();
}

static uint32_t cur[NS][CELLS];  /* the table, as the last round left it */
static bool taken[NS][CELLS];    /* written by a packet of this round */
static struct pkt round_pk[ROUND_MAX];
static uint32_t round_n;

static uint32_t fresh_value(uint8_t k, uint8_t c)
{
    uint32_t v;
    do
        v = c == 0 ? (uint32_t)(rich() | rich() << 8) : rich();
    while (v == cur[k][c]);
    return v;
}

/* Is range r free on servo k this round? */
static bool range_free(uint8_t k, uint8_t r)
{
    for (uint8_t c = range_first[r]; c < range_first[r] + range_cells[r]; c++)
        if (taken[k][c])
            return false;
    return true;
}

/* The data bytes of range r for servo k, marked as written by p. */
static uint8_t range_data(struct pkt *p, uint8_t k, uint8_t r, uint8_t *out)
{
    uint8_t n = 0;
    for (uint8_t c = range_first[r]; c < range_first[r] + range_cells[r]; c++) {
        uint32_t v = fresh_value(k, c);
        p->eff[k][c] = (int32_t)v;
        taken[k][c] = true;
        out[n++] = (uint8_t)v;
        if (c == 0)
            out[n++] = (uint8_t)(v >> 8);
    }
    return n;
}

/* One random packet of the round, a broadcast (SYNC WRITE or WRITE) or one addressed
 * to a servo (WRITE, READ, PING); false if no cell is left for its kind. */
static bool make_packet(struct pkt *p, bool broadcast)
{
    memset(p, 0, sizeof *p);
    memset(p->eff, 0xFF, sizeof p->eff);
    uint8_t kind = (uint8_t)(broadcast ? rnd() % 5u : 5u + rnd() % 3u);
    uint8_t par[90], n = 0, r = (uint8_t)(rnd() % 5u);
    uint8_t k = (uint8_t)(rnd() % NS);
    p->to = prop_id[k];
    if (kind <= 2u) { /* SYNC WRITE to the servos for which the range is free, and
                       * slices for IDs nobody has (ignored: bytes around the others) */
        p->to = PROTO_ID_BROADCAST;
        p->ins = INS_SYNC_WRITE;
        uint8_t len = (uint8_t)(range_cells[r] + (range_first[r] == 0 ? 1u : 0u));
        par[n++] = cell_addr[range_first[r]];
        par[n++] = len;
        uint8_t first = (uint8_t)(rnd() % NS), slices = 0;
        for (uint8_t j = 0; j < NS + 2u; j++) {
            if (j >= NS) { /* a stranger: 0xD6, 0x5E */
                if (rnd() % 2u) {
                    par[n++] = j == NS ? 0xD6u : 0x5Eu;
                    for (uint8_t i = 0; i < len; i++)
                        par[n++] = rich();
                }
                continue;
            }
            uint8_t s = (uint8_t)((first + j) % NS);
            if (!range_free(s, r) || rnd() % 3u != 0)
                continue;
            par[n++] = prop_id[s];
            n += range_data(p, s, r, &par[n]);
            slices++;
        }
        if (!slices)
            return false;
    } else if (kind <= 4u) { /* broadcast WRITE: every servo */
        for (uint8_t s = 0; s < NS; s++)
            if (!range_free(s, r))
                return false;
        p->to = PROTO_ID_BROADCAST;
        p->ins = INS_WRITE;
        par[n++] = cell_addr[range_first[r]];
        uint8_t d[4];
        uint8_t dn = range_data(p, 0, r, d);
        for (uint8_t s = 1; s < NS; s++) /* one value for all */
            for (uint8_t c = range_first[r]; c < range_first[r] + range_cells[r]; c++) {
                p->eff[s][c] = p->eff[0][c];
                taken[s][c] = true;
            }
        memcpy(&par[n], d, dn);
        n += dn;
    } else if (kind == 5u) { /* WRITE to one servo, answered */
        if (!range_free(k, r))
            return false;
        p->ins = INS_WRITE;
        par[n++] = cell_addr[range_first[r]];
        n += range_data(p, k, r, &par[n]);
    } else if (kind == 6u) { /* READ of the three cells, answered */
        p->ins = INS_READ;
        par[n++] = REG_MOVING_SPEED;
        par[n++] = 4;
    } else { /* PING, answered */
        p->ins = INS_PING;
    }
    p->ends_burst = p->to != PROTO_ID_BROADCAST;
    p->n = (uint8_t)proto_build_packet(p->b, p->to, p->ins, par, n);
    return true;
}

/* The value cell c of servo k holds after packets 0..upto-1 of the round, all but the
 * damaged one (dmg) executed. */
static uint32_t model(uint8_t k, uint8_t c, uint32_t upto, int dmg)
{
    uint32_t v = cur[k][c];
    for (uint32_t i = 0; i < upto; i++)
        if ((int)i != dmg && round_pk[i].eff[k][c] >= 0)
            v = (uint32_t)round_pk[i].eff[k][c];
    return v;
}

static struct {
    uint32_t rounds, packets, bytes, kinds[3], between, chance, answered, whole;
} stats;

/* Is traced frame i of servo k packet j of the round? */
static bool trace_is(uint8_t k, uint32_t i, uint32_t j)
{
    const struct trace *t = &trace[k];
    return j < round_n && t->len[i] == round_pk[j].n - 2u &&
           memcmp(t->b[i], &round_pk[j].b[2], t->len[i]) == 0;
}

/* Servo k's traced frames that are not other servos' answers (it hears the bus). */
static uint32_t own_frames(uint8_t k, uint32_t *idx)
{
    const struct trace *t = &trace[k];
    uint32_t n = 0;
    for (uint32_t i = 0; i < t->n; i++) {
        bool answer = false;
        for (uint32_t a = 0; a < heard.n && !answer; a++)
            answer = heard.b[a][2] != prop_id[k] && t->len[i] == heard.len[a] - 2u &&
                     memcmp(t->b[i], &heard.b[a][2], t->len[i]) == 0;
        if (!answer)
            idx[n++] = i;
    }
    return n;
}

/* Are servo k's frames idx[i..n) the round's packets from j on, but `skip`, exactly? */
static bool rest_is(uint8_t k, const uint32_t *idx, uint32_t i, uint32_t n, uint32_t j, int skip)
{
    for (; i < n; i++, j++) {
        if ((int)j == skip)
            j++;
        if (!trace_is(k, idx[i], j))
            return false;
    }
    if ((int)j == skip)
        j++;
    return j >= round_n;
}

/* Did servo k execute the packets of the round as sent? Those before `at` (the first
 * packet the damage can touch: the damaged one dmg, or the one after an inserted byte)
 * in order; from `at` on, the rest in order but dmg, which may still have come whole (an
 * extra D5 before its header's 5D, say; then *dmg_ran is set). Any other frame there can
 * only be one nobody sent that passed its 8-bit checksum by chance: then false, and the
 * round is not judged further (that frame did what it did, and may have taken what
 * followed with it). A packet lost or repeated after frames as expected fails. */
static bool trace_matches(uint8_t k, int dmg, uint32_t at, bool *dmg_ran)
{
    static uint32_t idx[TRACE_MAX];
    uint32_t n = own_frames(k, idx);
    for (uint32_t i = 0; i < at; i++)
        if (i >= n || !trace_is(k, idx[i], i))
            fail_msg("round %u: servo %02X did not execute packet %u of %u as sent (the "
                     "damage is at packet %u)", stats.rounds, prop_id[k], i, round_n, at);
    if (rest_is(k, idx, at, n, at, dmg))
        return true;
    if (dmg >= 0 && (int)at == dmg && trace_is(k, idx[at], at) &&
        rest_is(k, idx, at + 1u, n, at, dmg)) {
        *dmg_ran = true; /* it came whole */
        return true;
    }
    /* A chance frame: not a packet sent (or a copy of one that came too), then the rest
     * in order, less some it may have taken with it. */
    bool chance = at < n;
    for (uint32_t j = 0; j < round_n && chance; j++) {
        if (!trace_is(k, idx[at], j))
            continue;
        chance = false; /* a copy: the packet itself came too, before or after */
        for (uint32_t i = 0; i < n && !chance; i++)
            chance = i != at && trace_is(k, idx[i], j);
    }
    bool rest = false;
    for (uint32_t j = at; j <= round_n && chance && !rest; j++)
        rest = rest_is(k, idx, at + 1u, n, j, dmg);
    if (!rest)
        fail_msg("round %u: servo %02X lost or repeated a packet from packet %u on (of %u; "
                 "the damaged one: %d)", stats.rounds, prop_id[k], at, round_n, dmg);
    return false; /* a chance checksum where the damage is */
}

/* One round: packets generated, one byte of them damaged (deleted, inserted or
 * corrupted), sent as a host sends (broadcasts back to back, an addressed packet ends a
 * burst and the host waits for its answer or answer_wait_us()), then judged. */
static void property_round(void)
{
    memset(taken, 0, sizeof taken);
    round_n = 0;
    /* Bursts: up to 12 broadcasts back to back, then an addressed packet. */
    uint32_t bursts = 1u + rnd() % 3u;
    for (uint32_t burst = 0; burst < bursts; burst++) {
        uint32_t m = rnd() % 13u;
        for (uint32_t i = 0; i <= m && round_n < ROUND_MAX; i++)
            for (uint32_t tries = 0; tries < 8u; tries++) { /* until one fits */
                struct pkt *p = &round_pk[round_n];
                if (!make_packet(p, i < m))
                    continue;
                bool twice = false; /* a READ or PING like an earlier one: which came? */
                for (uint32_t j = 0; j < round_n && !twice; j++)
                    twice = round_pk[j].n == p->n && memcmp(round_pk[j].b, p->b, p->n) == 0;
                if (!twice) {
                    round_n++;
                    break;
                }
            }
    }
    round_pk[round_n - 1u].ends_burst = true;
    uint32_t total = 0;
    for (uint32_t i = 0; i < round_n; i++)
        total += round_pk[i].n;

    /* The damage: at byte d of the round's bytes; an insertion goes before it. */
    uint32_t kind = rnd() % 3u; /* 0 delete, 1 insert, 2 corrupt */
    uint32_t d = rnd() % (kind == 1u ? total + 1u : total);
    uint8_t v = rich();
    int dmg = -1;
    uint32_t first = round_n; /* the first packet the damage can touch */
    for (uint32_t i = 0, at = 0; i < round_n; at += round_pk[i++].n) {
        if (d >= at && d < at + round_pk[i].n && !(kind == 1u && d == at))
            dmg = (int)i; /* an insertion between two packets damages neither */
        if (first == round_n && d < at + round_pk[i].n)
            first = i;
    }
    stats.kinds[kind]++;
    stats.between += dmg < 0;
    stats.packets += round_n;
    stats.bytes += total;

    memset(trace, 0, sizeof trace);
    heard.n = 0;
    uint32_t at = 0, answered_from[ROUND_MAX];
    int answer_of[ROUND_MAX];
    uint8_t burst[ROUND_MAX * 96u + 1u];
    uint32_t bn = 0;
    for (uint32_t i = 0; i < round_n; i++) {
        const struct pkt *p = &round_pk[i];
        for (uint32_t j = 0; j < p->n; j++, at++) {
            uint8_t b = p->b[j];
            if (at == d && kind == 1u)
                burst[bn++] = v;
            if (at == d && kind == 0u)
                continue;
            if (at == d && kind == 2u)
                b = v == b ? (uint8_t)~b : v;
            burst[bn++] = b;
        }
        if (i + 1u == round_n && d == total && kind == 1u)
            burst[bn++] = v; /* inserted after the last byte */
        answer_of[i] = -1;
        if (!p->ends_burst)
            continue;
        answered_from[i] = heard.n;
        send(burst, bn);
        bn = 0;
        uint32_t deadline = bus.now_us + answer_wait_us();
        while (p->to != PROTO_ID_BROADCAST && (int32_t)(deadline - bus.now_us) > 0 &&
               (answer_of[i] = heard_from(p->to, answered_from[i])) < 0)
            step();
    }
    /* The line rests: whatever waited behind the broken frame is out. */
    run_until(bus.now_us + frame_rx_gap_us(bus.host_baud) + 3000u);

    bool chance = false, dmg_ran = false;
    for (uint8_t k = 0; k < NS; k++)
        chance = !trace_matches(k, dmg, first, &dmg_ran) || chance;
    stats.chance += chance;
    stats.whole += dmg >= 0 && dmg_ran;
    if (dmg_ran)
        dmg = -1; /* it came whole after all: executed like the others */
    if (!chance) {
        for (uint32_t i = 0; i < round_n; i++) {
            const struct pkt *p = &round_pk[i];
            if (p->to == PROTO_ID_BROADCAST || (int)i == dmg)
                continue;
            if (answer_of[i] < 0)
                fail_msg("round %u: packet %u (INS %02X to %02X) not answered (damaged: %d)",
                         stats.rounds, i, p->ins, p->to, dmg);
            const uint8_t *a = heard.b[answer_of[i]];
            stats.answered++;
            if (p->ins == INS_PING)
                continue;
            assert_int_equal(a[4], 0); /* ERR */
            if (p->ins != INS_READ)
                continue;
            uint8_t k = 0;
            while (prop_id[k] != p->to)
                k++;
            assert_int_equal(a[3], 6);
            for (uint8_t c = 0; c < CELLS; c++) {
                uint32_t got = c == 0 ? (uint32_t)(a[5] | a[6] << 8) : a[5u + 1u + c];
                if (got != model(k, c, i, dmg))
                    fail_msg("round %u: READ %u of %02X: cell %u is %X, expected %X",
                             stats.rounds, i, p->to, c, got, model(k, c, i, dmg));
            }
        }
    }
    /* The table, read with packets nobody damaged. */
    for (uint8_t k = 0; k < NS; k++) {
        uint8_t t[4];
        read_regs(prop_id[k], REG_MOVING_SPEED, 4, t);
        uint32_t got[CELLS] = {(uint32_t)(t[0] | t[1] << 8), t[2], t[3]};
        for (uint8_t c = 0; c < CELLS; c++) {
            if (!chance && got[c] != model(k, c, round_n, dmg))
                fail_msg("round %u: servo %02X cell %u is %X, expected %X (damaged %d of %u, "
                         "%s at byte %u of %u)", stats.rounds, prop_id[k], c, got[c],
                         model(k, c, round_n, dmg), dmg, round_n,
                         kind == 0 ? "deleted" : kind == 1 ? "inserted" : "corrupted", d,
                         total);
            cur[k][c] = got[c];
        }
    }
    assert_nothing_dropped();
    stats.rounds++;
}

static void property_run(uint8_t code, uint32_t baud, uint32_t rounds, uint32_t seed)
{
    /* Register 18 bit 4 off: a broadcast whose ID byte is damaged into a servo's ID
     * would be answered "checksum error" while the host still sends the rest of its
     * burst, and that answer's collision is damage of its own. */
    open_bus(prop_board, prop_id, NS, code, baud);
    rng = seed;
    memset(&stats, 0, sizeof stats);
    for (uint8_t k = 0; k < NS; k++) {
        uint8_t t[4];
        read_regs(prop_id[k], REG_MOVING_SPEED, 4, t);
        cur[k][0] = (uint32_t)(t[0] | t[1] << 8);
        cur[k][1] = t[2];
        cur[k][2] = t[3];
    }
    for (uint32_t r = 0; r < rounds; r++)
        property_round();
    printf("%u baud: %u rounds, %u packets (%u bytes); damage: %u deleted, %u inserted "
           "(%u between packets), %u corrupted (%u damaged packets came whole); %u "
           "addressed answered; %u rounds with a frame that passed its checksum by chance; "
           "at most %u receiver records in use\n",
           baud, stats.rounds, stats.packets, stats.bytes, stats.kinds[0], stats.kinds[1],
           stats.between, stats.kinds[2], stats.whole, stats.answered, stats.chance,
           most_records);
    /* A chance checksum (1 in 256 per broken candidate) excuses a round: rare. */
    assert_true(stats.chance * 100u <= stats.rounds);
}

/* RX_BUS_ROUNDS_PERCENT (environment) runs that share of each baud's rounds, the same
 * seeds: short.rx_bus, in ctest -L fast, runs 10 %; unit.rx_bus all of them. Either way
 * the sample must have met every kind of damage (deleted, inserted, inserted between two
 * packets, corrupted, a damaged packet that came whole) and answers to judge. */
static void lost_byte_costs_one_packet_property(void **state)
{
    (void)state;
    static const struct {
        uint8_t code;
        uint32_t baud, rounds, seed;
    } runs[] = {{FAST_CODE, FAST_BAUD, 3000, 0x12345678u},
                {4, 115200, 1000, 0x9E3779B9u},
                {2, 9600, 150, 0x7F4A7C15u}};
    const char *env = getenv("RX_BUS_ROUNDS_PERCENT");
    uint32_t percent = env && *env ? (uint32_t)strtoul(env, NULL, 10) : 100u;
    uint32_t kinds[3] = {0, 0, 0}, between = 0, whole = 0, answered = 0;
    for (size_t r = 0; r < sizeof runs / sizeof runs[0]; r++) {
        uint32_t n = runs[r].rounds * percent / 100u;
        property_run(runs[r].code, runs[r].baud, n > 0u ? n : 1u, runs[r].seed);
        for (int k = 0; k < 3; k++)
            kinds[k] += stats.kinds[k];
        between += stats.between;
        whole += stats.whole;
        answered += stats.answered;
    }
    assert_true(kinds[0] > 0u && kinds[1] > 0u && kinds[2] > 0u);
    assert_true(between > 0u && whole > 0u && answered > 0u);
}

/* ---- no frame dropped: 1 Mbaud back to back, with the store's idle pre-erase --------- */

/* Issue 25, "no frame is dropped silently": frames back to back at about 1 Mbaud (and at
 * the top rate), among them EEPROM writes that fill the store's page, so that it
 * compacts into its spare page in the middle of the burst. The store's pages hold old
 * data, so the page after that one must be erased before the next compaction: the
 * store's idle pre-erase. The host model stalls the main loop for 40 ms per erase, as
 * an STM32F1's flash does (hal_host.h, erase_stall_us): a stall is what can drop frames,
 * so the test needs it. Every frame must be executed, the receiver must count no drop,
 * no erase may fall inside the burst, and the pre-erase must still happen once the line
 * rests (else the next compaction would erase inline, in the middle of some burst). */
static void no_frame_dropped_back_to_back_at_1mbaud_with_pre_erase(void **state)
{
    (void)state;
    const uint8_t codes[] = {8, 10};
    const uint32_t bauds[] = {921600, 1792000};
    for (size_t run = 0; run < 2; run++) {
        const struct board *b[] = {&board_foot};
        const uint8_t id[] = {1};
        open_bus_on(b, id, 1, codes[run], bauds[run], true);
        struct node *n = &bus.node[0];
        struct store *st = &n->servo.store;
        /* Fill the store's page to a few records from full, fast: the commit budget
         * (a separate matter, docs/persistence.md) out of the way. */
        st->refill_us = 0;
        for (uint8_t v = 0; (HAL_FLASH_PAGE_BYTES - st->next) / 6u > 6u; v++)
            write8(1, REG_TEMPERATURE_LIMIT, (uint8_t)(70u + (v & 1u)));
        run_ms(5);
        assert_true(st->spare_blank); /* pre-erased while the line rested */
        uint8_t page = st->active;

        n->hal.erase_stall_us = 40000;
        uint32_t erases = 0;
        for (uint8_t p = 0; p < HAL_FLASH_PAGES; p++)
            erases += n->hal.flash.erases[p];
        /* 400 broadcast WRITEs back to back: acceleration, deceleration, and every
         * eighth the temperature limit (a commit, then the compaction). */
        static uint8_t burst[400 * 8];
        uint32_t len = 0;
        for (uint32_t k = 0; k < 400; k++) {
            uint8_t w[2] = {k % 8u == 7u ? REG_TEMPERATURE_LIMIT
                            : k % 2u    ? REG_DECELERATION : REG_ACCELERATION,
                            k % 8u == 7u ? (uint8_t)(72u + (k / 8u) % 2u) : (uint8_t)(1u + k % 200u)};
            len += proto_build_packet(&burst[len], PROTO_ID_BROADCAST, INS_WRITE, w, 2);
        }
        uint32_t before = dispatched[0];
        send(burst, len);
        uint32_t during = 0;
        for (uint8_t p = 0; p < HAL_FLASH_PAGES; p++)
            during += n->hal.flash.erases[p];
        run_ms(100); /* the line rests */
        uint32_t after = 0;
        for (uint8_t p = 0; p < HAL_FLASH_PAGES; p++)
            after += n->hal.flash.erases[p];
        if (dispatched[0] - before != 400u || n->servo.rx.overruns)
            fail_msg("%u baud: %u of 400 frames executed, %u dropped (erases during the "
                     "burst: %u)", bauds[run], dispatched[0] - before, n->servo.rx.overruns,
                     during - erases);
        assert_int_not_equal(st->active, page); /* it compacted in the burst ... */
        assert_int_equal(during, erases);       /* ... into the page erased before it */
        assert_int_equal(after, erases + 1u);   /* the next one, erased once it rested */
        assert_true(st->spare_blank);
        uint8_t t[2], temp;
        read_regs(1, REG_ACCELERATION, 2, t);
        read_regs(1, REG_TEMPERATURE_LIMIT, 1, &temp);
        assert_int_equal(t[0], 1u + 398u % 200u);
        assert_int_equal(t[1], 1u + 397u % 200u);
        assert_int_equal(temp, 72u + (399u / 8u) % 2u);
        assert_nothing_dropped();
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(issue25_sync_write_without_its_id_keeps_the_write_behind_it),
        cmocka_unit_test(issue25_junk_with_nested_headers_keeps_the_next_three_packets),
        cmocka_unit_test(lost_byte_costs_one_packet_property),
        cmocka_unit_test(no_frame_dropped_back_to_back_at_1mbaud_with_pre_erase),
    };
    return cmocka_run_group_tests(tests, 0, 0);
}
