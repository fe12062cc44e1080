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
 *   2. no answer to a broadcast other than PING;
 *   3. every answer is well-formed: D5 5D, the servo's own ID (the one in force when the
 *      frame arrived), LEN = the bytes that follow it, the 8-bit sum of ID to the last
 *      parameter as its last byte; and only a frame for that ID or a broadcast gets one. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "../identity_check.h"
#include "fuzz.h"
#include "hal_host.h"
#include "proto.h"
#include "servo.h"

#define MAX_VIRTUAL_US 1000000000u /* 1000 s: far from the 32-bit clock's wrap */

const char fuzz_target_name[] = "fuzz_frame";

static struct hal hal;
static struct servo servo;
static uint8_t factory[REGS_SIZE];

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
    factory[REG_FIRMWARE_VERSION] = servo.fw_version;
    answer.pending = false;
}

/* One main-loop pass with the control loop frozen, watching what it dispatches and
 * sends. Returns false when nothing happened. */
static bool poll_once(void)
{
    uint8_t tail = servo.rx.ready_tail;
    uint32_t sends = hal.sends, log_from = hal.log_len;
    servo.motion.tick_us = hal.now_us; /* no control tick is due */
    hal.motor.last_us = hal.now_us;    /* the plant does not move */
    servo_poll(&servo);
    bool dispatched = servo.rx.ready_tail != tail;
    if (dispatched) {
        /* The slot the ring's old tail named, untouched until the next byte arrives. */
        uint8_t e = servo.rx.ready[tail & (FRAME_READY - 1u)];
        const uint8_t *buf = servo.rx.slot[e].buf; /* a slot's frame or the data block */
        uint8_t status = servo.rx.slot[e].status;
        bool ping = status == FRAME_OK && buf[2] == INS_PING;
        if (servo.link.state != LINK_IDLE) {
            /* An answer is scheduled, so the settings in force are still those the frame
             * arrived under (new ones apply once the answer is out). */
            uint8_t my_id = servo.link.id;
            FUZZ_CHECK(buf[0] == my_id || (buf[0] == PROTO_ID_BROADCAST && ping));
            answer.pending = true;
            answer.id = my_id;
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
        return servo.rx.ready_tail != servo.rx.ready_head;
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
static void run_until(uint32_t t, bool at_end)
{
    for (;;) {
        uint32_t next = t;
        if (servo.link.state == LINK_WAITING && (int32_t)(servo.link.due_us - next) < 0)
            next = servo.link.due_us;
        if (servo.link.state == LINK_SENDING && (int32_t)(hal.tx_end_us - next) < 0)
            next = hal.tx_end_us;
        if (servo.rx.in_frame) {
            uint32_t timeout = servo.rx.last_us + servo.rx.gap_us + servo.rx.byte_us + 1u;
            if ((int32_t)(timeout - next) < 0)
                next = timeout;
        }
        if ((int32_t)(next - hal.now_us) <= 0)
            next = t; /* already past: the last pass saw it (a reply waits for rx idle) */
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
    uint8_t head = servo.rx.ready_head, in_frame = servo.rx.in_frame;
    servo_rx_isr(&servo, b);
    /* A pass finds work only if the byte ended a frame (published, or dropped: the
     * receiver is idle again) or an answer waits; otherwise it is skipped, as it would
     * change nothing a later pass does not do the same way. */
    if (servo.rx.ready_head != head || servo.rx.in_frame != in_frame ||
        servo.link.state != LINK_IDLE)
        poll_idle();
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
