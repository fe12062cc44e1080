/* dispatch.c - decode, validate and execute instruction packets; decide whether and
 * when they are answered (PROTOCOL.md §3.2, §4). One table holds every instruction and
 * the rules checked before its handler (dispatch.h). */
#include <string.h>

#include "dispatch.h"
#include "hal.h"
#include "ident.h"
#include "loader.h"
#include "command.h"
#include "motion.h"
#include "proto.h"
#include "servo.h"
#include "write.h"

#if REGS_WITH_TEXT
#define NAME(n) , n
#else
#define NAME(n)
#endif
#define NO_SPEED 0xFFu

void dispatch_factory_reset(struct servo *s)
{
    uint8_t version = s->regs.mem[REG_FIRMWARE_VERSION]; /* the running image's, kept */
    command_reset(s);
    regs_reset(&s->regs); /* what differs from the factory value is marked for the store */
    regs_set(&s->regs, REG_FIRMWARE_VERSION, version);
    s->held.n = 0;
    traj_clear(&s->traj);
    motion_init(s);
    link_settings_written(&s->link); /* ID, baud, delay, level, terminator: after the answer */
}

static uint8_t do_ping(struct servo *s, const uint8_t *p, uint8_t n, struct dispatch_result *res)
{
    (void)p;
    (void)n;
    /* §4.1: `03 01 ERR`: the 0x01 sits where ERR usually is, ERR follows. */
    res->data[0] = safety_err(&s->safety);
    res->n = 1;
    return 0x01u;
}

static uint8_t do_read(struct servo *s, const uint8_t *p, uint8_t n, struct dispatch_result *res)
{
    (void)n;
    if (p[1] == 0u || p[0] >= REGS_SIZE || p[1] > REGS_SIZE - p[0])
        return ERR_INSTRUCTION;
    regs_read(&s->regs, p[0], p[1], res->data);
    res->n = p[1];
    return 0;
}

static uint8_t do_write(struct servo *s, const uint8_t *p, uint8_t n, struct dispatch_result *res)
{
    (void)res;
    return write_registers(s, p[0], &p[1], (uint8_t)(n - 1u));
}

static uint8_t do_reg_write(struct servo *s, const uint8_t *p, uint8_t n,
                            struct dispatch_result *res)
{
    (void)res;
    if (!regs_write_valid(&s->regs, p[0], &p[1], (uint8_t)(n - 1u)))
        return ERR_INSTRUCTION;
    s->held.addr = p[0];
    s->held.n = (uint8_t)(n - 1u);
    memcpy(s->held.data, &p[1], s->held.n);
    regs_set(&s->regs, REG_REGISTERED, 1);
    return 0;
}

static uint8_t do_action(struct servo *s, const uint8_t *p, uint8_t n, struct dispatch_result *res)
{
    (void)p;
    (void)n;
    (void)res;
    if (s->held.n == 0u)
        return ERR_INSTRUCTION;
    uint8_t held = s->held.n;
    s->held.n = 0;
    regs_set(&s->regs, REG_REGISTERED, 0);
    return write_registers(s, s->held.addr, s->held.data, held);
}

static uint8_t do_reset(struct servo *s, const uint8_t *p, uint8_t n, struct dispatch_result *res)
{
    (void)p;
    (void)n;
    (void)res;
    dispatch_factory_reset(s);
    return 0;
}

static uint8_t do_start_end(struct servo *s, const uint8_t *p, uint8_t n,
                            struct dispatch_result *res)
{
    (void)n;
    (void)res;
    if ((p[0] != 1u && p[0] != 2u) || regs_speed_mode(&s->regs))
        return ERR_INSTRUCTION;
    return command_start_end(s, p[0]);
}

/* SYNC WRITE: addr, L, then (id, L bytes) per servo; each servo takes its own slice. */
static uint8_t do_sync_write(struct servo *s, const uint8_t *p, uint8_t n,
                             struct dispatch_result *res)
{
    (void)res;
    if (p[1] == 0u)
        return ERR_INSTRUCTION;
    uint16_t stride = (uint16_t)(p[1] + 1u); /* L = 255 must not wrap to a stride of 0 */
    uint16_t body = (uint16_t)(n - 2u);
    if (body == 0u || body % stride != 0u)
        return ERR_INSTRUCTION;
    for (uint16_t i = 0; i < body; i = (uint16_t)(i + stride))
        if (p[2u + i] == link_id(&s->link))
            return write_registers(s, p[0], &p[3u + i], p[1]);
    return 0;
}

static uint8_t do_traj_write(struct servo *s, const uint8_t *p, uint8_t n,
                             struct dispatch_result *res)
{
    (void)res;
    uint8_t err = traj_write(&s->traj, &s->regs, p, n);
    if (!err)
        command_traj_written(s); /* a running trajectory never takes new points mid-run */
    return err;
}

static uint8_t do_traj_action(struct servo *s, const uint8_t *p, uint8_t n,
                              struct dispatch_result *res)
{
    (void)p;
    (void)n;
    (void)res;
    if (traj_empty(&s->traj))
        return ERR_INSTRUCTION;
    command_traj_action(s);
    return 0;
}

/* CUSTOM MOVE (§4.8) sub 0x01 (relative, 4 or 6 bytes) and 0x02 (absolute, 6 bytes). */
static uint8_t do_custom_move(struct servo *s, const uint8_t *p, uint8_t n,
                              struct dispatch_result *res)
{
    (void)res;
    if ((n != 5u && n != 7u) || (p[0] == 0x02u && n != 7u))
        return ERR_INSTRUCTION; /* relative: with or without ramps; absolute: with them */
    struct custom_move m = {
        .absolute = p[0] == 0x02u,
        .target = proto_get16(&p[1]),
        .speed = proto_get16(&p[3]),
    };
    if (n == 7u) { /* §4.8: written into the ramp registers */
        m.has_ramps = 1;
        m.acc = p[5];
        m.dec = p[6];
    }
    command_custom_move(s, &m);
    return 0;
}

/* Issue 27's identity sub-command: ident.c answers at ID 0xFF, or not at all. Not
 * inlined: inlining it costs the arm image 56 B more. */
__attribute__((noinline)) static uint8_t do_ident(struct servo *s, const uint8_t *p, uint8_t n,
                                                  struct dispatch_result *res)
{
    ident_frame(s, &p[1], (uint8_t)(n - 1u), res->broadcast, res->end_us);
    return 0;
}

/* Every instruction, once (§4): code, rules, parameter bytes min..max, the offset of a
 * speed parameter whose 0 is a stop (rule 3) or NO_SPEED, handler, the SDK's name. One
 * list yields both the table (rules, for dispatch, the SDK and the tests) and the switch
 * that calls the handlers, which the compiler can then inline. */
/* cppcheck-suppress misra-c2012-20.7 ; an X-macro list: X names a macro (docs/lint.md) */
#define INSTRUCTIONS(X)                                                                      \
    X(INS_PING, INS_ANSWER_ALWAYS | INS_IN_UPDATE, 0, 0, NO_SPEED, do_ping, "ping")         \
    X(INS_READ, INS_ANSWER_LEVEL1 | INS_IN_UPDATE, 2, 2, NO_SPEED, do_read, "read")         \
    X(INS_WRITE, INS_COMMITS, 2, 255, NO_SPEED, do_write, "write")                          \
    X(INS_REG_WRITE, 0, 2, 255, NO_SPEED, do_reg_write, "reg_write")                        \
    X(INS_ACTION, INS_COMMITS, 0, 0, NO_SPEED, do_action, "action")                         \
    X(INS_RESET, INS_COMMITS, 0, 0, NO_SPEED, do_reset, "reset")                            \
    X(INS_START_END, INS_COMMITS, 1, 1, NO_SPEED, do_start_end, "start_end")                \
    X(INS_SYNC_WRITE, INS_COMMITS | INS_BROADCAST_ONLY, 2, 255, NO_SPEED, do_sync_write,    \
      "sync_write")                                                                          \
    X(INS_TRAJ_WRITE, 0, 1, 255, NO_SPEED, do_traj_write, "trajectory_write")               \
    X(INS_TRAJ_ACTION, INS_MOVES, 0, 0, NO_SPEED, do_traj_action, "trajectory_action")      \
    X(INS_CUSTOM, 0, 1, 255, NO_SPEED, do_custom, "custom")

/* CUSTOM's sub-commands (§4.8), the same way; n counts the sub-command's own parameters.
 * The §10 update sub-commands (0xFC, 0xFE) are frames of their own, taken before
 * dispatch (update.h). */
/* cppcheck-suppress misra-c2012-20.7 ; an X-macro list: X names a macro (docs/lint.md) */
#define CUSTOM_SUBS(X)                                                                       \
    X(0x01u, INS_MOVES, 4, 6, 2, do_custom_move, "move_relative")                           \
    X(0x02u, INS_MOVES, 6, 6, 2, do_custom_move, "move_absolute")                           \
    X(IDENT_SUB, INS_OWN_ANSWER | INS_COMMITS, 1, 255, NO_SPEED, do_ident, "identity")

#define ENTRY(code, flags, min_n, max_n, speed_at, run, name)                                 \
    {(code), (flags), (min_n), (max_n), (speed_at)NAME(name)},
const struct instruction dispatch_instructions[] = {INSTRUCTIONS(ENTRY)};
const uint8_t dispatch_instruction_count =
    sizeof dispatch_instructions / sizeof dispatch_instructions[0];
const struct instruction dispatch_custom[] = {CUSTOM_SUBS(ENTRY)};
const uint8_t dispatch_custom_count = sizeof dispatch_custom / sizeof dispatch_custom[0];

static const struct instruction *find(const struct instruction *t, uint8_t count, uint8_t code)
{
    for (uint8_t i = 0; i < count; i++)
        if (t[i].code == code)
            return &t[i];
    return NULL;
}

/* The rules of an entry, checked once, before its handler: lengths, broadcast, an update
 * session, and a motion command that may not start (a speed of 0 always passes). */
static uint8_t check(const struct servo *s, const struct instruction *in, const uint8_t *p,
                     uint8_t n, bool broadcast)
{
    if (!in || n < in->min_n || n > in->max_n)
        return ERR_INSTRUCTION;
    if ((in->flags & INS_BROADCAST_ONLY) && !broadcast)
        return ERR_INSTRUCTION;
    if (update_in_session(&s->update) && !(in->flags & INS_IN_UPDATE))
        return ERR_INSTRUCTION; /* an update session: the servo only reports */
    if ((in->flags & INS_MOVES) &&
        !(in->speed_at != NO_SPEED && proto_speed_is_stop(proto_get16(&p[in->speed_at]))) &&
        !command_may_move(s))
        return ERR_INSTRUCTION;
    return 0;
}

#define CALL(code, flags, min_n, max_n, speed_at, run, name)                                  \
    case (code):                                                                             \
        return (run)(s, p, n, res);

static uint8_t do_custom(struct servo *s, const uint8_t *p, uint8_t n, struct dispatch_result *res)
{
    const struct instruction *sub = find(dispatch_custom, dispatch_custom_count, p[0]);
    uint8_t err = check(s, sub, &p[1], (uint8_t)(n - 1u), true);
    if (err)
        return err; /* other subs and lengths (§4.8), a move that may not start, an update */
    res->own_answer = sub->flags & INS_OWN_ANSWER;
    switch (p[0]) {
        /* NOLINTNEXTLINE(bugprone-branch-clone): both moves share a handler, by design */
        CUSTOM_SUBS(CALL)
    default:
        return ERR_INSTRUCTION;
    }
}

static uint8_t run(struct servo *s, const struct instruction *in, const uint8_t *p, uint8_t n,
                   bool broadcast, struct dispatch_result *res)
{
    uint8_t err = check(s, in, p, n, broadcast);
    if (err)
        return err;
    switch (in->code) {
        INSTRUCTIONS(CALL)
    default:
        return ERR_INSTRUCTION;
    }
}

/* §3.2: is an instruction with these rules answered at this status return level? */
static bool level_answers(uint8_t level, uint8_t flags)
{
    return (flags & INS_ANSWER_ALWAYS) || level >= 2u ||
           (level == 1u && (flags & INS_ANSWER_LEVEL1));
}

void dispatch_frame(struct servo *s, const struct frame *f)
{
    struct link *l = &s->link;
    uint8_t id = f->buf[0];
    bool broadcast = id == PROTO_ID_BROADCAST;
    if (!broadcast && id != link_id(l))
        return;
    uint32_t at = link_reply_at(l, f->end_us);

    if (update_is_frame(f->buf, f->len)) { /* §10, checksum errors included (NAK) */
        if (!broadcast && loader_update_frame(s, f) == UPDATE_STARTED)
            command_coast(s); /* no motion during an update */
        return;
    }
    /* An error answer never replaces a good one that waits (docs/decisions.md): what
     * failed may be another servo's answer at this ID, and the host waits for ours. */
    bool quiet_errors = link_waiting_good(l);
    if (f->status != FRAME_OK) {
        /* Not executed; answered only where level 2 and register 18 bit 4 allow. */
        if (!broadcast && !quiet_errors && link_answers_checksum_errors(l))
            link_answer(s, id, (uint8_t)(safety_err(&s->safety) | ERR_CHECKSUM), 0, 0, at);
        return;
    }

    safety_packet_seen(&s->safety); /* §7.1: any valid packet for this servo feeds the heartbeat */
    const struct instruction *in =
        find(dispatch_instructions, dispatch_instruction_count, f->buf[2]);
    uint8_t n = (uint8_t)(f->buf[1] - 2u); /* LEN counts INS and CHK */
    struct dispatch_result res = {.broadcast = broadcast, .end_us = f->end_us};
    res.err = run(s, in, &f->buf[3], n, broadcast, &res);
    if (res.own_answer)
        return; /* answered by the handler, or not at all, errors included */
    uint8_t flags = in ? in->flags : 0u;
    if (broadcast && (!(flags & INS_ANSWER_ALWAYS) || res.err == ERR_INSTRUCTION))
        return; /* §3.2: nobody answers a broadcast but a good PING */
    if (!level_answers(link_level(l), flags))
        return;
    if (res.err & ERR_INSTRUCTION) {
        /* A frame of an error answer's shape (no parameters, the code an ERR byte
         * reporting an error: bit 7 clear, bit 4 or 5 set; no instruction has one) is
         * another servo's error answer at this ID (duplicate IDs): answering it made two
         * such servos answer each other for ever, the bus never free again and their
         * heartbeats fed by it (docs/decisions.md). (code & 0xB0) is then 0x10, 0x20 or
         * 0x30: one subtraction, one compare. */
        bool echo = n == 0u && (uint8_t)((f->buf[2] & 0xB0u) - 0x10u) < 0x30u;
        if (quiet_errors || echo || !link_answers_instruction_errors(l))
            return; /* not reported: silence, so the host never mistakes it for success */
        link_answer(s, id, (uint8_t)(safety_err(&s->safety) | ERR_INSTRUCTION), 0, 0, at);
        return;
    }
    if (broadcast) /* §4.1: one answer slot per ID, so a whole bus answers in turn */
        at += link_ping_slot_us(l);
    uint8_t err = (flags & INS_ANSWER_ALWAYS) ? res.err : (uint8_t)(safety_err(&s->safety) | res.err);
    link_answer(s, broadcast ? link_id(l) : id, err, res.data, res.n, at);
}
