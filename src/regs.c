/* regs.c - the control table: the single descriptor table of PROTOCOL.md §5.1 and the
 * operations every other module derives from it. */
#include <string.h>

#include "proto.h"
#include "regs.h"

#ifndef SERVO_FW_VERSION
#define SERVO_FW_VERSION 1
#endif

#if REGS_WITH_TEXT
#define TEXT(unit, flags, name, doc) , unit, flags, name, doc
#else
#define TEXT(unit, flags, name, doc)
#endif

#define R REG_ACCESS_R
#define W REG_ACCESS_W
#define RW REG_ACCESS_RW
#define EE REG_AREA_EE
#define RAM REG_AREA_RAM

/* A row of the table in its compact form (regs.h), as the initialisers of its first
 * fields: a default, minimum or maximum the form cannot hold is a compile error (an array
 * of size -1), never a silently different value. */
#define REG_FITS(ok) (0u * sizeof(char[(ok) ? 1 : -1]))
#define REG_MAX_CODE(size, max) ((size) == 2u ? (max) >> 8 : (max))
#define REG_MAX_OF(size, code) ((size) == 2u ? ((code) << 8) | 0xFFu : (code))
#define REG_ROW(size, access, area, variants, def_src, def, min, max)                         \
    (size), (access), (area), (min) + REG_FITS((min) <= 1u), (variants), (def_src),           \
        (def) + REG_FITS((def) <= 0xFFu),                                                     \
        REG_MAX_CODE(size, max) +                                                             \
            REG_FITS(REG_MAX_CODE(size, max) <= 0xFFu &&                                      \
                     REG_MAX_OF(size, REG_MAX_CODE(size, max)) == (max))

/* size, access, area, variants, default source, default, min, max, then for the host
 * tools (REGS_WITH_TEXT) unit, flags, name and doc */
const struct reg_desc regs_table[REGS_SIZE] = {
    [REG_MODEL_NUMBER] = {REG_ROW(2, R, EE, REG_V_ALL, REG_DEF_MODEL, 0, 0, 0xFFFF)
        TEXT(REG_UNIT_NONE, 0, "model_number", "Model number of the board.")},
    [REG_FIRMWARE_VERSION] = {REG_ROW(1, R, EE, REG_V_ALL, REG_DEF_FIRMWARE, 0, 0, 0xFF)
        TEXT(REG_UNIT_NONE, 0, "firmware_version", "Firmware version of the running image.")},
    [REG_ID] = {REG_ROW(1, RW, EE, REG_V_ALL, REG_DEF_CONST, REGS_FACTORY_ID, 0, PROTO_ID_MAX)
        TEXT(REG_UNIT_NONE, 0, "id", "Bus ID. Takes effect after the answer to the write has been sent.")},
    [REG_BAUD_RATE] = {REG_ROW(1, RW, EE, REG_V_ALL, REG_DEF_CONST, 0, 0, 10)
        TEXT(REG_UNIT_NONE, 0, "baud_rate", "Baud rate code (0 = the variant's default, see the baud table). "
                          "Takes effect after the answer has been sent. A code the servo's clock "
                          "cannot make within 2 % is refused with an instruction error: a servo "
                          "whose crystal failed runs on a fall-back clock, and on the 8 MHz one "
                          "codes 6-10 are out of reach, so their refusal reports it.")},
    [REG_RETURN_DELAY] = {REG_ROW(1, RW, EE, REG_V_ALL, REG_DEF_RETURN_DELAY, 0, 0, 255)
        TEXT(REG_UNIT_DELAY, 0, "return_delay", "Delay between the last request byte and the answer.")},
    [REG_CW_LIMIT] = {REG_ROW(2, RW, EE, REG_V_ALL, REG_DEF_CONST, 0, 0, 0x7FFF)
        TEXT(REG_UNIT_POSITION, 0, "cw_angle_limit", "Lower angle limit. Must not exceed the CCW limit. Both limits 0 "
                               "= speed mode.")},
    [REG_CCW_LIMIT] = {REG_ROW(2, RW, EE, REG_V_ALL, REG_DEF_MAX_ANGLE, 0, 0, 0x7FFF)
        TEXT(REG_UNIT_POSITION, 0, "ccw_angle_limit", "Upper angle limit; factory value is the board's range.")},
    [REG_TEMPERATURE_LIMIT] = {REG_ROW(1, RW, EE, REG_V_ALL, REG_DEF_CONST, 80, 0, 255)
        TEXT(REG_UNIT_TEMP, 0, "temperature_limit", "Over-temperature threshold.")},
    [REG_CURRENT_LIMIT] = {REG_ROW(1, RW, EE, REG_V_ALL, REG_DEF_CURRENT, 0, 0, 255)
        TEXT(REG_UNIT_CURRENT, 0, "current_limit", "Over-current threshold.")},
    [REG_RESOLUTION] = {REG_ROW(1, RW, EE, REG_V_ALL, REG_DEF_CONST, 10, 1, 255)
        TEXT(REG_UNIT_RES, 0, "angle_resolution", "Size of one position unit. Changing it stops motion, clears "
                                 "the trajectory and rescales the limits and the goal.")},
    [REG_STATUS_RETURN_LEVEL] = {REG_ROW(1, RW, EE, REG_V_ALL, REG_DEF_CONST, 2, 0, 2)
        TEXT(REG_UNIT_NONE, 0, "status_return_level", "0: answer PING only; 1: PING and READ; 2: everything.")},
    [REG_HEARTBEAT_ENABLE] = {REG_ROW(1, RW, EE, REG_V_ALL, REG_DEF_CONST, 1, 0, 1)
        TEXT(REG_UNIT_NONE, 0, "heartbeat_enable", "1: stop when no valid packet arrives for 500 ms.")},
    [REG_UNLOAD_CONDITIONS] = {REG_ROW(1, RW, EE, REG_V_ALL, REG_DEF_CONST, 0x7F, 0, 0x7F)
        TEXT(REG_UNIT_NONE, 0, "unload_conditions", "Bit 6 stall, 3 under-voltage, 2 over-voltage, 1 over-current, "
                                  "0 over-temperature: unload on it. Bit 5/4: report "
                                  "instruction/checksum errors.")},
    [REG_HOMING_ZERO_SIDE] = {REG_ROW(1, RW, EE, REG_V_ALL, REG_DEF_CONST, 1, 1, 2)
        TEXT(REG_UNIT_NONE, 0, "homing_zero_side", "1: zero at the CW (negative) end; 2: at the CCW end.")},
    [REG_RS485_TERMINATION] = {REG_ROW(1, RW, EE, REG_V_ALL, REG_DEF_CONST, 0, 0, 1)
        TEXT(REG_UNIT_NONE, 0, "rs485_termination", "1: switch the 120 ohm bus terminator on.")},
    [REG_BASE_ACCELERATION] = {REG_ROW(1, RW, EE, REG_V_B, REG_DEF_CONST, 36, 0, 255)
        TEXT(REG_UNIT_ACCEL, 0, "base_acceleration", "Acceleration of the base (0 = no ramp).")},
    [REG_BASE_DECELERATION] = {REG_ROW(1, RW, EE, REG_V_B, REG_DEF_CONST, 36, 0, 255)
        TEXT(REG_UNIT_ACCEL, 0, "base_deceleration", "Deceleration of the base (0 = no ramp).")},
    [REG_HOMING] = {REG_ROW(1, RW, RAM, REG_V_ALL, REG_DEF_CONST, 0, 0, 1)
        TEXT(REG_UNIT_NONE, 0, "homing", "Write 1 to start homing, 0 to stop. Reads: low nibble as written, high "
                       "nibble 0 never, 1 running, 2 done, 3 failed.")},
    [REG_CLEAR_UNLOAD] = {REG_ROW(1, W, RAM, REG_V_ALL, REG_DEF_CONST, 0, 1, 1)
        TEXT(REG_UNIT_NONE, 0, "clear_unload", "Write 1 to clear a latched protection unload. Reads 0.")},
    [REG_GOAL_POSITION] = {REG_ROW(2, RW, RAM, REG_V_ALL, REG_DEF_CONST, 0, 0, 0xFFFF)
        TEXT(REG_UNIT_POSITION, 0, "goal_position", "Target of a move, clamped to the angle limits. Starts equal to "
                              "the present position. Base: relative to the present angle.")},
    [REG_MOVING_SPEED] = {REG_ROW(2, RW, RAM, REG_V_ALL, REG_DEF_CONST, 0, 0, 0xFFFF)
        TEXT(REG_UNIT_DIR_SPEED, 0, "moving_speed", "Cruise speed; in speed mode the turning speed. 0 stops.")},
    [REG_ACCELERATION] = {REG_ROW(1, RW, RAM, REG_V_NOT_B, REG_DEF_CONST, 36, 0, 255)
        TEXT(REG_UNIT_ACCEL, 0, "acceleration", "Acceleration (0 = no ramp).")},
    [REG_DECELERATION] = {REG_ROW(1, RW, RAM, REG_V_NOT_B, REG_DEF_CONST, 36, 0, 255)
        TEXT(REG_UNIT_ACCEL, 0, "deceleration", "Deceleration (0 = no ramp).")},
    [REG_PRESENT_POSITION] = {REG_ROW(2, R, RAM, REG_V_WH, REG_DEF_CONST, 0, 0, 0xFFFF)
        TEXT(REG_UNIT_POSITION, 0, "present_position", "Absolute present position.")},
    [REG_PRESENT_SPEED] = {REG_ROW(2, R, RAM, REG_V_ALL, REG_DEF_CONST, 0, 0, 0xFFFF)
        TEXT(REG_UNIT_SPEED, REG_FLAG_SIGNED, "present_speed", "Present speed, positive in the positive direction.")},
    [REG_TURNED_ANGLE] = {REG_ROW(2, R, RAM, REG_V_NOT_WH, REG_DEF_CONST, 0, 0, 0xFFFF)
        TEXT(REG_UNIT_POSITION, REG_FLAG_SIGNED, "turned_angle", "Turned angle, wrapping; relative on base and foot, absolute on "
                             "the arm.")},
    [REG_MOVING] = {REG_ROW(1, R, RAM, REG_V_ALL, REG_DEF_CONST, 0, 0, 1)
        TEXT(REG_UNIT_NONE, 0, "moving", "1 while a motion runs.")},
    [REG_BRAKE] = {REG_ROW(1, RW, RAM, REG_V_ALL, REG_DEF_CONST, 0, 0, 1)
        TEXT(REG_UNIT_NONE, 0, "brake", "1: stop at once and hold.")},
    [REG_REGISTERED] = {REG_ROW(1, R, RAM, REG_V_ALL, REG_DEF_CONST, 0, 0, 1)
        TEXT(REG_UNIT_NONE, 0, "registered", "1 while a REG WRITE is held.")},
    [REG_PRESENT_TEMPERATURE] = {REG_ROW(1, R, RAM, REG_V_ALL, REG_DEF_CONST, 0, 0, 255)
        TEXT(REG_UNIT_TEMP, 0, "present_temperature", "Present temperature.")},
    [REG_SLEEP] = {REG_ROW(1, RW, RAM, REG_V_ALL, REG_DEF_CONST, 0, 0, 1)
        TEXT(REG_UNIT_NONE, 0, "sleep", "1: torque off, low power; the servo still answers.")},
    [REG_PHOTO_SWITCHES] = {REG_ROW(1, R, RAM, REG_V_ALL, REG_DEF_CONST, 0, 0, 3)
        TEXT(REG_UNIT_NONE, 0, "photo_switches", "Bit 0 switch 1, bit 1 switch 2.")},
    [REG_MOVE_WITHOUT_REFERENCE] = {REG_ROW(1, RW, RAM, REG_V_ALL, REG_DEF_CONST, 0, 0, 1)
        TEXT(REG_UNIT_NONE, 0, "move_without_reference", "1: allow speed mode before homing has succeeded.")},
};

bool regs_applicable(const struct board *b, uint8_t addr)
{
    if (addr >= REGS_SIZE)
        return false;
    const struct reg_desc *d = &regs_table[addr];
    return d->size && (d->variants & REG_V(b->variant));
}

uint16_t regs_default(const struct board *b, uint8_t addr)
{
    const struct reg_desc *d = &regs_table[addr];
    switch (d->def_src) {
    case REG_DEF_MODEL:
        return b->model_number;
    case REG_DEF_FIRMWARE:
        return SERVO_FW_VERSION;
    case REG_DEF_RETURN_DELAY:
        return b->return_delay;
    case REG_DEF_MAX_ANGLE:
        return (uint16_t)(b->max_angle_ddeg / regs_table[REG_RESOLUTION].def);
    case REG_DEF_CURRENT:
        return b->current_limit;
    default:
        return d->def;
    }
}

uint16_t regs_get(const struct regs *r, uint8_t addr)
{
    if (regs_table[addr].size == 2)
        return r->half[addr >> 1]; /* one aligned load */
    return r->mem[addr];
}

void regs_set(struct regs *r, uint8_t addr, uint16_t value)
{
    const struct reg_desc *d = &regs_table[addr];
    if (d->area == REG_AREA_EE && (d->access & REG_ACCESS_W) && regs_get(r, addr) != value)
        r->ee_changed = 1;
    if (d->size == 2)
        r->half[addr >> 1] = value; /* one aligned store: never torn */
    else
        r->mem[addr] = (uint8_t)value;
}

/* Not inlined: one copy for its callers, smaller under -flto (measured). */
__attribute__((noinline)) void regs_set_lazy(struct regs *r, uint8_t addr, uint16_t value)
{
    uint8_t was = r->ee_changed;
    regs_set(r, addr, value);
    if (r->ee_changed && !was) {
        r->ee_changed = 0;
        r->ee_lazy = 1;
    }
}

void regs_reset(struct regs *r)
{
    for (uint8_t a = 0; a < REGS_SIZE; a++)
        if (regs_applicable(r->board, a))
            regs_set(r, a, regs_default(r->board, a));
}

void regs_init(struct regs *r, const struct board *b)
{
    memset(r->mem, 0, sizeof r->mem);
    r->board = b;
    regs_reset(r);
    r->ee_changed = 0;
    r->ee_lazy = 0;
}

bool regs_take_ee_changed(struct regs *r)
{
    bool changed = r->ee_changed != 0u;
    r->ee_changed = 0;
    return changed;
}

bool regs_take_ee_lazy(struct regs *r)
{
    bool changed = r->ee_lazy != 0u;
    r->ee_lazy = 0;
    return changed;
}

void regs_read(const struct regs *r, uint8_t addr, uint8_t count, uint8_t *out)
{
    /* Walk from the start of the register that holds addr, so a read that starts on a
     * high byte still sees that register's visibility. */
    for (uint8_t i = 0; i < count; i++) {
        uint8_t a = (uint8_t)(addr + i);
        uint8_t start = a;
        if (!regs_table[a].size && a && regs_table[a - 1].size == 2)
            start = (uint8_t)(a - 1);
        const struct reg_desc *d = &regs_table[start];
        bool visible = regs_applicable(r->board, start) && (d->access & REG_ACCESS_R);
        out[i] = visible ? r->mem[a] : 0;
    }
}

uint16_t regs_value(const uint8_t *p, uint8_t size)
{
    return size == 2 ? proto_get16(p) : p[0];
}

bool regs_write_valid(const struct regs *r, uint8_t addr, const uint8_t *data, uint8_t n)
{
    if (n == 0 || addr >= REGS_SIZE || n > REGS_SIZE - addr)
        return false;
    uint16_t cw = regs_get(r, REG_CW_LIMIT), ccw = regs_get(r, REG_CCW_LIMIT);
    for (uint8_t i = 0; i < n;) {
        uint8_t a = (uint8_t)(addr + i);
        const struct reg_desc *d = &regs_table[a];
        if (!regs_applicable(r->board, a) || !(d->access & REG_ACCESS_W) || d->size > n - i)
            return false;
        uint16_t v = regs_value(&data[i], d->size);
        if (!regs_in_range(a, v))
            return false;
        if (a == REG_CW_LIMIT)
            cw = v;
        if (a == REG_CCW_LIMIT)
            ccw = v;
        i = (uint8_t)(i + d->size);
    }
    return cw <= ccw;
}

bool regs_in_range(uint8_t addr, uint16_t v)
{
    return v >= regs_table[addr].min && v <= regs_max(&regs_table[addr]);
}

uint8_t regs_first_invalid(const struct regs *r)
{
    for (uint8_t a = 0; a < REGS_SIZE; a++) {
        const struct reg_desc *d = &regs_table[a];
        if (!regs_applicable(r->board, a) || !(d->access & REG_ACCESS_W) ||
            a == REG_CLEAR_UNLOAD)
            continue;
        uint16_t v = regs_get(r, a);
        if (a == REG_HOMING)
            v &= 0x0Fu; /* the high nibble is the status the servo reports */
        if (!regs_in_range(a, v))
            return a;
    }
    return regs_get(r, REG_CW_LIMIT) > regs_get(r, REG_CCW_LIMIT) ? REG_CW_LIMIT : REGS_SIZE;
}

uint64_t regs_mask(uint8_t addr, uint8_t n)
{
    uint64_t m = 0;
    for (uint8_t i = 0; i < n && addr + i < REGS_SIZE; i++)
        m |= (uint64_t)1 << (addr + i);
    return m;
}

bool regs_touches_area(uint8_t addr, uint8_t n, uint8_t area)
{
    for (uint8_t i = 0; i < n; i++)
        if (regs_table[addr + i].size && regs_table[addr + i].area == area)
            return true;
    return false;
}

bool regs_speed_mode(const struct regs *r)
{
    return r->board->variant == VARIANT_BASE ||
           (regs_get(r, REG_CW_LIMIT) == 0 && regs_get(r, REG_CCW_LIMIT) == 0);
}

uint16_t regs_clamp_goal(const struct regs *r, uint16_t goal)
{
    if (regs_speed_mode(r))
        return goal;
    uint16_t lo = regs_get(r, REG_CW_LIMIT), hi = regs_get(r, REG_CCW_LIMIT);
    return goal < lo ? lo : goal > hi ? hi : goal;
}

uint16_t regs_present_position(const struct regs *r)
{
    return regs_get(r, regs_position_addr(r->board));
}

uint8_t regs_ramp_addr(const struct board *b)
{
    return b->variant == VARIANT_BASE ? REG_BASE_ACCELERATION : REG_ACCELERATION;
}
