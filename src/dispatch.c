/* dispatch.c - decode, validate and execute instruction packets; decide whether and
 * when they are answered (PROTOCOL.md §3.2, §4). */
#include <string.h>

#include "dispatch.h"
#include "hal.h"
#include "loader.h"
#include "motion.h"
#include "proto.h"
#include "servo.h"

/* Outcome of one instruction: per-packet ERR bits and the answer's parameters. */
struct result {
    uint8_t err;
    uint8_t n;
    uint8_t data[REGS_SIZE];
};

static void rescale(struct regs *r, uint8_t addr, uint8_t old_res, uint8_t new_res)
{
    uint32_t v = ((uint32_t)regs_get(r, addr) * old_res + new_res / 2u) / new_res;
    uint32_t max = regs_table[addr].max;
    regs_set(r, addr, (uint16_t)(v > max ? max : v));
}

uint8_t dispatch_write(struct servo *s, uint8_t addr, const uint8_t *data, uint8_t n)
{
    struct regs *r = &s->regs;
    if (!regs_write_valid(r, addr, data, n) || !motion_write_allowed(s, addr, data, n))
        return ERR_INSTRUCTION;
    uint8_t old_res = r->mem[REG_RESOLUTION];
    for (uint8_t i = 0; i < n;) {
        uint8_t a = (uint8_t)(addr + i);
        uint8_t size = regs_table[a].size;
        uint16_t v = regs_value(&data[i], size);
        if (a == REG_HOMING)
            v = (uint16_t)((r->mem[REG_HOMING] & 0xF0u) | v); /* status nibble stays */
        else if (a == REG_GOAL_POSITION)
            v = regs_clamp_goal(r, v);
        if (a != REG_CLEAR_UNLOAD) /* a command, reads 0 */
            regs_set(r, a, v);
        i = (uint8_t)(i + size);
    }
    uint8_t new_res = r->mem[REG_RESOLUTION];
    if (new_res != old_res) {
        /* §5: limits and goal keep meaning the same angles; the trajectory is dropped
         * and the motion layer stops (it sees the write to register 13). */
        uint16_t was = regs_present_position(r); /* still in the old unit */
        bool inside = !regs_speed_mode(r) && was >= regs_get(r, REG_CW_LIMIT) &&
                      was <= regs_get(r, REG_CCW_LIMIT);
        rescale(r, REG_CW_LIMIT, old_res, new_res);
        rescale(r, REG_CCW_LIMIT, old_res, new_res);
        rescale(r, REG_GOAL_POSITION, old_res, new_res);
        traj_clear(&s->traj);
        /* A shaft within its limits stays within them: a limit rounds to the nearest new
         * unit, and the position, which nothing moves, may round the other way (homing
         * holds on the switch edge, up to half a unit past the limit it measured). The
         * limit then widens by that unit rather than the servo moving on its own. */
        int32_t here = motion_position(s);
        if (inside && here >= 0 && here <= 0x7FFF) {
            if (here > (int32_t)regs_get(r, REG_CCW_LIMIT))
                regs_set(r, REG_CCW_LIMIT, (uint16_t)here);
            if (here < (int32_t)regs_get(r, REG_CW_LIMIT))
                regs_set(r, REG_CW_LIMIT, (uint16_t)here);
        }
    }
    motion_on_write(s, addr, n);
    return 0;
}

void dispatch_factory_reset(struct servo *s)
{
    motion_reset(s);
    regs_reset(&s->regs); /* what differs from the factory value is marked for the store */
    s->regs.mem[REG_FIRMWARE_VERSION] = s->fw_version;
    s->held.n = 0;
    traj_clear(&s->traj);
    motion_init(s);
}

static void do_read(struct servo *s, const uint8_t *p, uint8_t n, struct result *res)
{
    if (n != 2u || p[1] == 0u || p[0] >= REGS_SIZE || p[1] > REGS_SIZE - p[0]) {
        res->err = ERR_INSTRUCTION;
        return;
    }
    /* Interrupt-side writers update 16-bit registers with one store; copying with them
     * masked means no register is seen half old, half new. */
    uint32_t irq = hal_irq_save(s->hal);
    regs_read(&s->regs, p[0], p[1], res->data);
    hal_irq_restore(s->hal, irq);
    res->n = p[1];
}

static uint8_t do_reg_write(struct servo *s, const uint8_t *p, uint8_t n)
{
    if (n < 2u || !regs_write_valid(&s->regs, p[0], &p[1], (uint8_t)(n - 1u)))
        return ERR_INSTRUCTION;
    s->held.addr = p[0];
    s->held.n = (uint8_t)(n - 1u);
    memcpy(s->held.data, &p[1], s->held.n);
    s->regs.mem[REG_REGISTERED] = 1;
    return 0;
}

static uint8_t do_action(struct servo *s, uint8_t n)
{
    if (n != 0u || s->held.n == 0u)
        return ERR_INSTRUCTION;
    uint8_t held = s->held.n;
    s->held.n = 0;
    s->regs.mem[REG_REGISTERED] = 0;
    return dispatch_write(s, s->held.addr, s->held.data, held);
}

/* SYNC WRITE: addr, L, then (id, L bytes) per servo; each servo takes its own slice. */
static uint8_t do_sync_write(struct servo *s, const uint8_t *p, uint8_t n)
{
    if (n < 2u || p[1] == 0u)
        return ERR_INSTRUCTION;
    uint16_t stride = (uint16_t)(p[1] + 1u); /* L = 255 must not wrap to a stride of 0 */
    uint16_t body = (uint16_t)(n - 2u);
    if (body == 0u || body % stride != 0u)
        return ERR_INSTRUCTION;
    for (uint16_t i = 0; i < body; i = (uint16_t)(i + stride))
        if (p[2u + i] == s->link.id)
            return dispatch_write(s, p[0], &p[3u + i], p[1]);
    return 0;
}

static uint8_t do_custom(struct servo *s, const uint8_t *p, uint8_t n)
{
    if (n < 1u)
        return ERR_INSTRUCTION;
    struct custom_move m = {0};
    if (p[0] == 0x01u && (n == 5u || n == 7u))
        m.absolute = 0;
    else if (p[0] == 0x02u && n == 7u)
        m.absolute = 1;
    else
        return ERR_INSTRUCTION; /* other subs, including the update (0xFC/0xFE) for now */
    m.target = proto_get16(&p[1]);
    m.speed = proto_get16(&p[3]);
    if (n == 7u) {
        m.has_ramps = 1;
        m.acc = p[5];
        m.dec = p[6];
    }
    /* All or nothing (§3.2): a refused move changes no ramp register either. */
    uint8_t err = motion_custom_allowed(s, &m);
    if (err)
        return err;
    if (m.has_ramps) { /* §4.8: written into the ramp registers */
        uint8_t a = regs_ramp_addr(s->board);
        regs_set(&s->regs, a, m.acc);
        regs_set(&s->regs, (uint8_t)(a + 1u), m.dec);
    }
    motion_custom_move(s, &m);
    return 0;
}

static void execute(struct servo *s, uint8_t ins, const uint8_t *p, uint8_t n, bool broadcast,
                    struct result *res)
{
    switch (ins) {
    case INS_PING:
        if (n != 0u) {
            res->err = ERR_INSTRUCTION;
            return;
        }
        /* §4.1: `03 01 ERR`: the 0x01 sits where ERR usually is, ERR follows. */
        res->err = 0x01u;
        res->data[0] = safety_err(&s->safety);
        res->n = 1;
        return;
    case INS_READ:
        do_read(s, p, n, res);
        return;
    case INS_WRITE:
        res->err = n < 2u ? ERR_INSTRUCTION : dispatch_write(s, p[0], &p[1], (uint8_t)(n - 1u));
        return;
    case INS_REG_WRITE:
        res->err = do_reg_write(s, p, n);
        return;
    case INS_ACTION:
        res->err = do_action(s, n);
        return;
    case INS_RESET:
        if (n != 0u)
            res->err = ERR_INSTRUCTION;
        else
            dispatch_factory_reset(s);
        return;
    case INS_START_END:
        if (n != 1u || (p[0] != 1u && p[0] != 2u) || regs_speed_mode(&s->regs))
            res->err = ERR_INSTRUCTION;
        else
            res->err = motion_start_end(s, p[0]);
        return;
    case INS_SYNC_WRITE:
        res->err = broadcast ? do_sync_write(s, p, n) : ERR_INSTRUCTION;
        return;
    case INS_TRAJ_WRITE:
        res->err = traj_write(&s->traj, &s->regs, p, n);
        return;
    case INS_TRAJ_ACTION:
        if (n != 0u || traj_empty(&s->traj))
            res->err = ERR_INSTRUCTION;
        else
            res->err = motion_traj_action(s);
        return;
    case INS_CUSTOM:
        res->err = do_custom(s, p, n);
        return;
    default:
        res->err = ERR_INSTRUCTION;
        return;
    }
}

/* §3.2: which instructions a status return level answers. */
static bool level_answers(uint8_t level, uint8_t ins)
{
    return ins == INS_PING || level >= 2u || (level == 1u && ins == INS_READ);
}

void dispatch_frame(struct servo *s, const struct frame *f)
{
    struct link *l = &s->link;
    uint8_t id = f->buf[0];
    bool broadcast = id == PROTO_ID_BROADCAST;
    if (!broadcast && id != l->id)
        return;
    uint32_t at = link_reply_at(l, f->end_us);

    if (update_is_frame(f->buf, f->len)) { /* §10, checksum errors included (NAK) */
        if (!broadcast && loader_update_frame(s, f) == UPDATE_STARTED)
            motion_torque_off(s); /* no motion during an update */
        return;
    }
    if (f->status != FRAME_OK) {
        /* Not executed; answered only where level 2 and register 18 bit 4 allow. */
        if (!broadcast && l->level == 2u && (l->report & UNLOAD_REPORT_CHECKSUM))
            link_answer(s, id, (uint8_t)(safety_err(&s->safety) | ERR_CHECKSUM), 0, 0, at);
        return;
    }

    safety_packet_seen(&s->safety); /* §7.1: any valid packet for this servo feeds the heartbeat */
    uint8_t ins = f->buf[2];
    uint8_t n = (uint8_t)(f->buf[1] - 2u); /* LEN counts INS and CHK */
    struct result res = {0};
    if (update_in_session(&s->update) && ins != INS_PING && ins != INS_READ)
        res.err = ERR_INSTRUCTION; /* an update session: the servo only reports */
    else
        execute(s, ins, &f->buf[3], n, broadcast, &res);

    if (broadcast && (ins != INS_PING || res.err == ERR_INSTRUCTION))
        return; /* §3.2: nobody answers a broadcast but a good PING */
    if (!level_answers(l->level, ins))
        return;
    if (res.err & ERR_INSTRUCTION) {
        if (!(l->report & UNLOAD_REPORT_INSTRUCTION))
            return; /* not reported: silence, so the host never mistakes it for success */
        link_answer(s, id, (uint8_t)(safety_err(&s->safety) | ERR_INSTRUCTION), 0, 0, at);
        return;
    }
    if (broadcast) /* §4.1: one answer slot per ID, so a whole bus answers in turn */
        at += (uint32_t)l->id * link_bytes_us(l->baud, 9u);
    uint8_t err = ins == INS_PING ? res.err : (uint8_t)(safety_err(&s->safety) | res.err);
    link_answer(s, broadcast ? l->id : id, err, res.data, res.n, at);
}
