/* fuzz_frame.c - one servo's receiver and dispatcher (frame_rx, dispatch, link, regs,
 * store; the application's main loop servo_poll) fed arbitrary bytes with arbitrary
 * inter-byte gaps. The control loop is frozen (no control tick runs, the plant does not
 * move), so virtual time costs nothing: it advances only as far as the bytes and gaps
 * need, and from one event of the servo (an answer due, an answer sent, the receiver's
 * time-out) to the next. The whole servo in real time is fuzz_bus's.
 *
 * Input: the format of fuzz_bus.c, so its seeds serve here too: byte 0 picks the board,
 * byte 1 the ID (0: factory ID 1), then the wire from the host:
 *   FF FF      one data byte FF
 *   FF FE      power cycle (the flash survives)
 *   FF FD k    plan a flash power cut at the (k & 15) + 1-th next program or erase, kind
 *              (k >> 4) % 3 (clean, done, torn); the servo reboots when it happens
 *   FF g       (g <= FC) idle line for (g + 1)^2 x 10 us
 *   other b    one data byte, 10 bit-times at the servo's baud rate
 *
 * Invariants, after every dispatched frame and every answer sent (abort on violation):
 *   1. the identity registers are unchanged; every register is in its range; CW <= CCW;
 *   2. no answer to a broadcast other than PING and the identity sub-command (0x11);
 *   3. every answer is well-formed: D5 5D, the servo's own ID (the one in force when the
 *      frame arrived; 0xFF for the identity sub-command, include/ident.h), LEN = the bytes that follow it, the 8-bit sum of ID to the last
 *      parameter as its last byte; and only a frame for that ID or a broadcast gets one.
 *
 * An input whose byte 0 is F0 or more is instead a packet sequence with one damaged
 * byte (issue 25; byte 0 % BOARD_COUNT still picks the board, byte 1 the ID):
 *   byte 2     damage: (b % 3) delete, insert, corrupt
 *   bytes 3-4  where, little-endian, modulo the sequence's bytes (an insertion goes
 *              before that byte; modulo one more, it may go after the last)
 *   byte 5     the byte inserted, or written over the old one (rich(): see below)
 *   then       packets, each from a kind byte k and the bytes it needs: k % 5 is a
 *              broadcast WRITE, a SYNC WRITE, or to an ID a WRITE, READ or PING; the ID is
 *              the servo's, 5D or D5 by (k >> 3) % 3; WRITEs and SYNC WRITEs cover the
 *              moving speed, acceleration and deceleration (RAM: they start nothing at
 *              rest in position mode); every parameter byte is rich(): D5 or 5D half of
 *              the time. At most 16 packets.
 * The host sends broadcasts back to back; after a packet to an ID it waits for the
 * answer (the §1 time-out, the longest return delay and the answer itself).
 * Invariants 1-3, and 4: every packet but the damaged one is dispatched, once, in order,
 * and every one addressed to the servo is answered - unless the receiver counted a frame
 * it had to drop (overruns: never silently), or dispatched a frame nobody sent, which
 * passed its 8-bit checksum by chance (1 in 256 for each broken candidate). */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "../identity_check.h"
#include "fuzz.h"
#include "hal_host.h"
#include "ident.h"
#include "proto.h"
#include "servo.h"

#define MAX_VIRTUAL_US 1000000000u /* 1000 s: far from the 32-bit clock's wrap */

const char fuzz_target_name[] = "fuzz_frame";

static struct hal hal;
static struct servo servo;
static uint8_t factory[REGS_SIZE];

/* Invariant 4: the packets of a sequence input, and the frames dispatched meanwhile. */
#define SEQ_PACKETS 16u
#define SEQ_BYTES 48u
static struct {
    bool on;
    uint32_t n;                            /* packets */
    uint8_t b[SEQ_PACKETS][SEQ_BYTES];     /* each, D5 5D to CHK */
    uint8_t len[SEQ_PACKETS];
    uint32_t seen;                         /* frames dispatched good */
    uint8_t got[2u * SEQ_PACKETS][SEQ_BYTES];
    uint8_t got_len[2u * SEQ_PACKETS];
    bool got_answer[2u * SEQ_PACKETS];     /* an answer was scheduled for it */
} seq;

/* What the answer being sent must look like. */
static struct {
    bool pending;
    uint8_t id;
} answer;

/* A factory-fresh servo's HAL of each board, made once (hal_host_init and the factory
 * image cost far more than one input): everything but the transmit log, which is last. */
#define HAL_FRESH_BYTES offsetof(struct hal, log)
_Static_assert(offsetof(struct hal, log) + sizeof hal.log == sizeof(struct hal),
               "the transmit log is the last member of struct hal");
static struct hal fresh[BOARD_COUNT];
static bool fresh_made[BOARD_COUNT];

static uint8_t checked[REGS_SIZE]; /* the table as last checked */

/* Invariant 1, whenever the table differs from the one last checked. */
static void check_table(void)
{
    if (memcmp(checked, servo.regs.mem, sizeof checked) == 0)
        return;
    memcpy(checked, servo.regs.mem, sizeof checked);
    FUZZ_CHECK(identity_unchanged(&servo, factory));
    FUZZ_CHECK(regs_first_invalid(&servo.regs) == REGS_SIZE);
}

/* Invariant 3 on the bytes the UART just sent (hal log entries from..log_len). */
static void check_sent(uint32_t from)
{
    uint32_t n = hal.log_len - from;
    FUZZ_CHECK(answer.pending);
    answer.pending = false;
    FUZZ_CHECK(n >= 6u && n <= PROTO_STATUS_MAX);
    uint8_t b[PROTO_STATUS_MAX];
    for (uint32_t i = 0; i < n; i++)
        b[i] = hal_host_tx(&hal, from + i)->byte;
    FUZZ_CHECK(b[0] == PROTO_HEADER0 && b[1] == PROTO_HEADER1);
    FUZZ_CHECK(b[2] == answer.id);
    FUZZ_CHECK(b[3] == n - 4u);
    FUZZ_CHECK(proto_sum(&b[2], (uint16_t)(n - 3u)) == b[n - 1u]);
}

static void power_up(void)
{
    hal_host_reboot(&hal);
    servo_init(&servo, servo.board, &hal);
    factory[REG_FIRMWARE_VERSION] = servo.regs.mem[REG_FIRMWARE_VERSION];
    answer.pending = false;
}

/* One main-loop pass with the control loop frozen, watching what it dispatches and
 * sends. Returns false when nothing happened. */
static bool poll_once(void)
{
    uint8_t tail = servo.rx.rec_tail;
    /* The frame a pass would take (its bytes stay untouched until the next byte). */
    const struct frame *next = frame_rx_peek(&servo.rx);
    struct frame taken = next ? *next : (struct frame){0, 0, 0, NULL};
    uint32_t sends = hal.sends, log_from = hal.log_len;
    struct link before = servo.link;
    servo.motion.tick_us = hal.now_us; /* no control tick is due */
    hal.motor.last_us = hal.now_us;    /* the plant does not move */
    servo_poll(&servo);
    bool dispatched = servo.rx.rec_tail != tail;
    if (dispatched) {
        if (!taken.buf) { /* published by this pass's own time-out check, then taken */
            FUZZ_CHECK(servo.rx.rec_tail == (uint8_t)(tail + 1u));
            taken = servo.rx.view;
        }
        const uint8_t *buf = taken.buf; /* a slot's frame or the data block */
        uint8_t status = taken.status;
        bool ping = status == FRAME_OK && buf[2] == INS_PING;
        uint16_t len = taken.len;
        /* A frame is executed while an earlier answer waits (its return delay, a PING
         * slot): only an answer this frame scheduled or replaced is its own. */
        bool scheduled = servo.link.state != LINK_IDLE &&
                         (before.state != LINK_WAITING || before.due_us != servo.link.due_us ||
                          before.tx_len != servo.link.tx_len ||
                          memcmp(before.tx, servo.link.tx, sizeof before.tx) != 0);
        if (seq.on && status == FRAME_OK && seq.seen < 2u * SEQ_PACKETS) {
            bool fits = len <= SEQ_BYTES; /* a longer one is nobody's: got_len 0 */
            seq.got_len[seq.seen] = fits ? (uint8_t)len : 0u;
            if (fits)
                memcpy(seq.got[seq.seen], buf, len);
            seq.got_answer[seq.seen++] = scheduled;
        }
        if (scheduled) {
            /* An answer is scheduled, so the settings in force are still those the frame
             * arrived under (new ones apply once the answer is out). */
            uint8_t my_id = servo.link.id;
            /* The identity sub-command (include/ident.h) answers at ID 0xFF, broadcast
             * included: the one exception to invariants 2 and 3's ID. */
            bool ident = status == FRAME_OK && buf[2] == INS_CUSTOM && buf[1] > 3u &&
                         buf[3] == IDENT_SUB;
            FUZZ_CHECK(buf[0] == my_id || (buf[0] == PROTO_ID_BROADCAST && (ping || ident)));
            answer.pending = true;
            answer.id = ident ? PROTO_ID_INVALID : my_id;
        }
        check_table();
    }
    if (hal.sends != sends)
        check_sent(log_from);
    if (!hal.flash.powered || hal.restart_requested) { /* a planned cut, a restart */
        power_up();
        check_table();
    }
    return dispatched || hal.sends != sends;
}

/* Would another pass now find something to do? A frame waiting while the link is free,
 * an answer due, an answer sent. */
static bool work_left(void)
{
    switch (servo.link.state) {
    case LINK_IDLE:
        return servo.rx.rec_tail != servo.rx.rec_ready;
    case LINK_WAITING:
        return (int32_t)(hal.now_us - servo.link.due_us) >= 0 && !servo.rx.in_frame;
    default:
        return (int32_t)(hal.now_us - hal.tx_end_us) >= 0;
    }
}

/* Main-loop passes until there is nothing left to do now. */
static void poll_idle(void)
{
    do
        (void)poll_once();
    while (work_left());
}

/* Advance virtual time to t, passing the main loop at every event of the servo on the
 * way (an answer due, an answer sent, the receiver's time-out) and, if at_end, at t. The
 * servo does nothing else on its own that a later pass would not do the same way. */
/* Event at time e: the next one (in *next) if it is still to come and before *next.
 * One already past was seen by the last pass (a reply due waits for the receiver). */
static void event_at(uint32_t e, uint32_t *next)
{
    if ((int32_t)(e - hal.now_us) > 0 && (int32_t)(e - *next) < 0)
        *next = e;
}

static void run_until(uint32_t t, bool at_end)
{
    for (;;) {
        uint32_t next = t;
        if (servo.link.state == LINK_WAITING)
            event_at(servo.link.due_us, &next);
        if (servo.link.state == LINK_SENDING)
            event_at(hal.tx_end_us, &next);
        if (servo.rx.in_frame)
            event_at(servo.rx.last_us + servo.rx.gap_us + servo.rx.byte_us + 1u, &next);
        hal.now_us = next;
        if (next != t || at_end)
            poll_idle();
        if (next == t)
            return;
    }
}

static void send_byte(uint8_t b)
{
    uint32_t baud = hal.baud ? hal.baud : 9600u;
    run_until(hal.now_us + (10u * 1000000u + baud - 1u) / baud, false); /* its 10 bits */
    uint8_t ready = servo.rx.rec_ready, in_frame = servo.rx.in_frame;
    servo_rx_isr(&servo, b);
    /* A pass finds work only if the byte ended a frame (published, or dropped: the
     * receiver is idle again) or an answer waits; otherwise it is skipped, as it would
     * change nothing a later pass does not do the same way. */
    if (servo.rx.rec_ready != ready || servo.rx.in_frame != in_frame ||
        servo.link.state != LINK_IDLE)
        poll_idle();
}

/* D5 or 5D half of the time: the bytes that make headers. */
static uint8_t rich(uint8_t b)
{
    return (b & 3u) == 0 ? 0xD5u : (b & 3u) == 1u ? 0x5Du : b;
}

/* The packets of a sequence input (see the top), into seq. */
static void seq_build(struct fuzz_reader *r, uint8_t my_id)
{
    static const uint8_t addr[3] = {REG_MOVING_SPEED, REG_ACCELERATION, REG_DECELERATION};
    static const uint8_t size[3] = {2, 1, 1};
    const uint8_t ids[3] = {my_id, 0x5Du, 0xD5u};
    seq.n = 0;
    while (r->left && seq.n < SEQ_PACKETS) {
        uint8_t k = fuzz_get8(r), kind = k % 5u, p[40], n = 0;
        uint8_t to = kind < 2u ? PROTO_ID_BROADCAST : ids[(k >> 3) % 3u];
        uint8_t ins = kind == 1u ? INS_SYNC_WRITE : kind == 3u ? INS_READ
                      : kind == 4u ? INS_PING : INS_WRITE;
        uint8_t a = (uint8_t)(fuzz_get8(r) % 3u);
        if (ins == INS_READ) {
            p[n++] = REG_MOVING_SPEED;
            p[n++] = 4;
        } else if (ins == INS_SYNC_WRITE) {
            p[n++] = addr[a];
            p[n++] = size[a];
            for (uint8_t s = 0, slices = (uint8_t)(1u + fuzz_get8(r) % 4u); s < slices; s++) {
                p[n++] = ids[fuzz_get8(r) % 3u];
                for (uint8_t i = 0; i < size[a]; i++)
                    p[n++] = rich(fuzz_get8(r));
            }
        } else if (ins == INS_WRITE) {
            p[n++] = addr[a];
            for (uint8_t i = 0; i < size[a]; i++)
                p[n++] = rich(fuzz_get8(r));
        }
        seq.len[seq.n] = (uint8_t)proto_build_packet(seq.b[seq.n], to, ins, p, n);
        bool twice = false; /* two alike: which one came? Send it once */
        for (uint32_t i = 0; i < seq.n && !twice; i++)
            twice = seq.len[i] == seq.len[seq.n] && !memcmp(seq.b[i], seq.b[seq.n], seq.len[i]);
        seq.n += !twice;
    }
}

/* Is dispatched frame i packet j? */
static bool seq_is(uint32_t i, uint32_t j)
{
    return j < seq.n && seq.got_len[i] == seq.len[j] - 2u &&
           memcmp(seq.got[i], &seq.b[j][2], seq.got_len[i]) == 0;
}

/* Do dispatched frames from i on match the packets from j on, but `skip`, exactly? */
static bool seq_rest_is(uint32_t i, uint32_t j, int skip)
{
    for (; i < seq.seen; i++, j++) {
        if ((int)j == skip)
            j++;
        if (!seq_is(i, j))
            return false;
    }
    if ((int)j == skip)
        j++;
    return j >= seq.n;
}

/* Is dispatched frame i one nobody sent: not a packet sent, or a copy of one that came
 * too (before or after it)? */
static bool seq_unsent(uint32_t i)
{
    for (uint32_t j = 0; j < seq.n; j++) {
        if (!seq_is(i, j))
            continue;
        bool again = false;
        for (uint32_t k = 0; k < seq.seen && !again; k++)
            again = k != i && seq_is(k, j);
        if (!again)
            return false;
    }
    return true;
}

/* Are the dispatched frames from `at` on frames nobody sent that passed their checksums
 * by chance, in the damaged packet's place, followed by the rest of the packets in order,
 * less some they may have taken with them? A chance frame may end on a packet's header
 * (its checksum byte the header's 5D): that D5 5D is then the frame's payload (the rule
 * that keeps a sent frame ending in D5 5D whole, unit.frame_rx), the packet is lost, and
 * the hunt resumes inside it, where a D5 5D of its parameters may start a second chance
 * frame (2^-16 per damaged packet; fuzz_frame found one). Else frame `at` is a packet
 * sent, and the ones before it were lost. */
static bool seq_chance(uint32_t at, int damaged)
{
    for (uint32_t c = at; c < seq.seen && seq_unsent(c); c++)
        for (uint32_t j = at; j <= seq.n; j++)
            if (seq_rest_is(c + 1u, j, damaged))
                return true;
    return false; /* nothing where the damage is (the rest was lost), or a packet sent */
}

/* Invariant 4 after a sequence input. damaged: the damaged packet (-1: none, an
 * insertion between two packets); at: the first packet the damage can touch (the
 * damaged one, or the one after the inserted byte). The packets before it come as sent;
 * from it on, the rest come as sent but the damaged one, which may still come whole (an
 * extra D5 before its header's 5D, say). Any other frame there can only be one nobody
 * sent that passed its checksum by chance: it did what it did (a WRITE of the ID, a
 * RESET) and may have taken what followed with it, so the rest is not judged. Every
 * packet for the servo that came as sent was answered. Unless the receiver counted a
 * drop: then it said so. */
static void seq_check(int damaged, uint32_t at, uint32_t overruns, uint8_t my_id)
{
    if (servo.rx.overruns != overruns)
        return;
    uint32_t i = 0;
    for (; i < at; i++)
        FUZZ_CHECK(i < seq.seen && seq_is(i, i));
    bool whole = (int)at == damaged && at < seq.seen && seq_is(at, at);
    if (!seq_rest_is(at, at, damaged) && !(whole && seq_rest_is(at + 1u, at, damaged))) {
        FUZZ_CHECK(seq_chance(at, damaged));
        return; /* a chance checksum where the damage is: it did what it did */
    }
    for (uint32_t k = 0; k < seq.seen; k++) /* every packet sent for the servo answered */
        for (uint32_t j = 0; j < seq.n; j++)
            if (seq_is(k, j) && seq.b[j][2] == my_id)
                FUZZ_CHECK(seq.got_answer[k]);
}

/* A sequence input: the packets sent as a host sends them, one byte damaged. */
static void seq_run(struct fuzz_reader *r)
{
    uint8_t kind = fuzz_get8(r) % 3u;
    uint32_t at = fuzz_get8(r);
    at |= (uint32_t)fuzz_get8(r) << 8;
    uint8_t v = rich(fuzz_get8(r));
    uint8_t my_id = servo.link.id;
    seq_build(r, my_id);
    uint32_t total = 0;
    for (uint32_t i = 0; i < seq.n; i++)
        total += seq.len[i];
    if (!total)
        return;
    at %= kind == 1u ? total + 1u : total;
    int damaged = -1;
    uint32_t first = seq.n; /* the first packet the damage can touch */
    for (uint32_t i = 0, from = 0; i < seq.n; from += seq.len[i++]) {
        if (at >= from && at < from + seq.len[i] && !(kind == 1u && at == from))
            damaged = (int)i;
        if (first == seq.n && at < from + seq.len[i])
            first = i;
    }
    seq.on = true;
    seq.seen = 0;
    uint32_t overruns = servo.rx.overruns, pos = 0;
    uint32_t wait = frame_rx_gap_us(hal.baud) + 255u * 500u + 20000u; /* + delay, answer */
    for (uint32_t i = 0; i < seq.n; i++) {
        for (uint32_t j = 0; j < seq.len[i]; j++, pos++) {
            if (pos == at && kind == 1u)
                send_byte(v);
            if (pos == at && kind == 0u)
                continue;
            send_byte(pos == at && kind == 2u ? (v == seq.b[i][j] ? (uint8_t)~v : v)
                                              : seq.b[i][j]);
        }
        if (i + 1u == seq.n && at == total && kind == 1u)
            send_byte(v);
        if (seq.b[i][2] != PROTO_ID_BROADCAST || i + 1u == seq.n)
            run_until(hal.now_us + wait, true);
    }
    seq.on = false;
    seq_check(damaged, first, overruns, my_id);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_progress();
    if (size < 2u)
        return 0;
    uint8_t bi = data[0] % BOARD_COUNT;
    const struct board *b = board_all[bi];
    if (!fresh_made[bi]) {
        hal_host_init(&fresh[bi]);
        hal_host_attach_board(&fresh[bi], b);
        hal_host_program_factory(&fresh[bi], b);
        fresh_made[bi] = true;
    }
    memcpy(&hal, &fresh[bi], HAL_FRESH_BYTES);
    servo_init(&servo, b, &hal);
    if (data[1]) {
        servo.regs.mem[REG_ID] = data[1] < PROTO_ID_BROADCAST ? data[1] : 1u;
        link_latch(&servo);
    }
    memcpy(factory, servo.regs.mem, sizeof factory);
    memset(checked, 0, sizeof checked);
    checked[0] = (uint8_t)~factory[0]; /* differs: the first check runs */
    answer.pending = false;
    check_table();

    struct fuzz_reader r = {data + 2, size - 2u};
    if (data[0] >= 0xF0u) {
        seq_run(&r);
        return 0;
    }
    for (struct fuzz_wire_event e; hal.now_us < MAX_VIRTUAL_US &&
                                   (e = fuzz_wire_next(&r)).kind != FUZZ_WIRE_END;) {
        switch (e.kind) {
        case FUZZ_WIRE_BYTE:
            send_byte(e.byte);
            break;
        case FUZZ_WIRE_POWER_CYCLE:
            power_up();
            check_table();
            break;
        case FUZZ_WIRE_CUT:
            hal.flash.cut_at = hal.flash.ops + e.cut_after;
            hal.flash.cut_kind = e.cut_kind;
            break;
        default: /* FUZZ_WIRE_IDLE */
            run_until(hal.now_us + e.idle_us, true);
            break;
        }
    }
    run_until(hal.now_us + 300000u, true); /* the last answers go out, whatever the delay */
    return 0;
}
