/* write.c - a host's write of registers (write.h): the table validates, the modules that
 * act on the touched registers may refuse, the table stores all of it, the modules act. */
#include <string.h>

#include "command.h"
#include "proto.h"
#include "servo.h"
#include "write.h"

#define BIT(a) ((uint64_t)1 << (a))
#define BITS2(a) (BIT(a) | BIT((a) + 1u))

/* Each hook hands its module only its own part of the servo (motion's is the motion
 * layer, which drives the motor from the table, the safety state and the trajectory). */
static uint8_t link_check(const struct servo *s, const struct reg_write *w)
{
    /* a fall-back clock makes not every rate: one it cannot make is refused */
    return link_baud_reachable(s, w->addr, w->data, w->n) ? 0u : ERR_INSTRUCTION;
}

static void link_act(struct servo *s, const struct reg_write *w)
{
    (void)w;
    link_settings_written(&s->link);
}

static uint8_t safety_check(const struct servo *s, const struct reg_write *w)
{
    (void)w;
    return safety_may_clear(&s->safety) ? 0u : ERR_INSTRUCTION; /* the cause is still there */
}

static void safety_act(struct servo *s, const struct reg_write *w)
{
    (void)w;
    safety_clear(&s->safety); /* nothing moves until the next motion command (§6.3) */
}

/* The hooks, once: registers acted on at a write, check, act; for the docs the owner,
 * the registers it reads as it works, and what it does. One list yields the table
 * (write_hooks[], for tools/regdoc.c and the tests) and the calls below, which the
 * compiler inlines. */
/* cppcheck-suppress misra-c2012-20.7 ; an X-macro list: X names a macro (docs/lint.md) */
#define HOOKS(X)                                                                             \
    X(BIT(REG_ID) | BIT(REG_BAUD_RATE) | BIT(REG_RETURN_DELAY) |                             \
          BIT(REG_STATUS_RETURN_LEVEL) | BIT(REG_UNLOAD_CONDITIONS) |                        \
          BIT(REG_RS485_TERMINATION),                                                        \
      link_check, link_act, "link", 0,                                                       \
      "in force once the answer to the write has left the wire (§1); 20 switches the RS485 " \
      "terminator then, and at power-up")                                                    \
    X(BIT(REG_CLEAR_UNLOAD), safety_check, safety_act, "safety",                             \
      BIT(REG_TEMPERATURE_LIMIT) | BIT(REG_CURRENT_LIMIT) | BIT(REG_HEARTBEAT_ENABLE) |      \
          BIT(REG_UNLOAD_CONDITIONS),                                                        \
      "25 clears a latched unload (refused while its cause lasts); 11, 12, 17 and 18 are "   \
      "read every control tick")                                                             \
    X(BITS2(REG_CW_LIMIT) | BITS2(REG_CCW_LIMIT) | BIT(REG_RESOLUTION) |                     \
          BIT(REG_HOMING_ZERO_SIDE) | BIT(REG_BASE_ACCELERATION) |                           \
          BIT(REG_BASE_DECELERATION) | BIT(REG_HOMING) | BITS2(REG_GOAL_POSITION) |          \
          BITS2(REG_MOVING_SPEED) | BIT(REG_ACCELERATION) | BIT(REG_DECELERATION) |          \
          BIT(REG_BRAKE) | BIT(REG_SLEEP),                                                   \
      command_write_check, command_written, "motion", BIT(REG_MOVE_WITHOUT_REFERENCE),       \
      "what the register means to the motor, at once (docs/motion.md); 49 is read when a "   \
      "motion command arrives")

#if REGS_WITH_TEXT
#define ENTRY(acts_on, check, act, owner, reads, effect) {(acts_on), (owner), (reads), (effect)},
#else
#define ENTRY(acts_on, check, act, owner, reads, effect) {(acts_on)},
#endif
const struct write_hook write_hooks[] = {HOOKS(ENTRY)};
const uint8_t write_hook_count = sizeof write_hooks / sizeof write_hooks[0];

uint8_t write_registers(struct servo *s, uint8_t addr, const uint8_t *data, uint8_t n)
{
    struct regs *r = &s->regs;
    if (!regs_write_valid(r, addr, data, n))
        return ERR_INSTRUCTION;
    const struct reg_write w = {addr, n, r->mem[REG_RESOLUTION], data, regs_mask(addr, n)};
#define CHECK(acts_on, check, act, owner, reads, effect)                                     \
    if (((acts_on) & w.touched) && (check)(s, &w))                                             \
        return ERR_INSTRUCTION;
    HOOKS(CHECK)
    for (uint8_t i = 0; i < n;) {
        uint8_t a = (uint8_t)(addr + i);
        uint8_t size = regs_table[a].size;
        /* An answered write of an EEPROM register is in flash before its answer, even
         * when RAM already held the value: the base's CUSTOM MOVE sets 21/22 in RAM
         * lazily, so such a write changed nothing and nothing was committed (lost at a
         * power cut). The store compares with what it saved: a value already in flash
         * costs nothing. */
        if (regs_table[a].area == REG_AREA_EE)
            r->ee_changed = 1;
        uint16_t v = regs_value(&data[i], size);
        if (a == REG_HOMING)
            v = (uint16_t)((r->mem[REG_HOMING] & 0xF0u) | v); /* the status nibble stays */
        else if (a == REG_GOAL_POSITION)
            v = regs_clamp_goal(r, v);
        if (a != REG_CLEAR_UNLOAD) /* a command: reads 0 */
            regs_set(r, a, v);
        i = (uint8_t)(i + size);
    }
#define ACT(acts_on, check, act, owner, reads, effect)                                       \
    if ((acts_on) & w.touched)                                                               \
        (act)(s, &w);
    HOOKS(ACT)
    return 0;
}
