/* regs.h - the control table (PROTOCOL.md §5): one descriptor per register drives
 * validation, factory defaults, READ/WRITE and the generated register reference. */
#ifndef REGS_H
#define REGS_H

#include <stdbool.h>
#include <stdint.h>

#include "board.h"

#define REGS_SIZE 50u
/* Every 16-bit register at an even address is one element of regs.half[]. */
_Static_assert(REGS_SIZE % 2u == 0u, "the table is read and written in half-words");
#define REGS_FACTORY_ID 1u /* register 3's factory value (PROTOCOL.md §5) */

/* 1: compile register names and descriptions in (host tools and docs); the MCU image
 * leaves them out to save flash. */
#ifndef REGS_WITH_TEXT
#define REGS_WITH_TEXT 0
#endif

/* Register addresses used by name in the core. */
enum {
    REG_MODEL_NUMBER = 0,
    REG_FIRMWARE_VERSION = 2,
    REG_ID = 3,
    REG_BAUD_RATE = 4,
    REG_RETURN_DELAY = 5,
    REG_CW_LIMIT = 6,
    REG_CCW_LIMIT = 8,
    REG_TEMPERATURE_LIMIT = 11,
    REG_CURRENT_LIMIT = 12,
    REG_RESOLUTION = 13,
    REG_STATUS_RETURN_LEVEL = 16,
    REG_HEARTBEAT_ENABLE = 17,
    REG_UNLOAD_CONDITIONS = 18,
    REG_HOMING_ZERO_SIDE = 19,
    REG_RS485_TERMINATION = 20,
    REG_BASE_ACCELERATION = 21,
    REG_BASE_DECELERATION = 22,
    REG_HOMING = 24,
    REG_CLEAR_UNLOAD = 25,
    REG_GOAL_POSITION = 30,
    REG_MOVING_SPEED = 32,
    REG_ACCELERATION = 34,
    REG_DECELERATION = 35,
    REG_PRESENT_POSITION = 36,
    REG_PRESENT_SPEED = 38,
    REG_TURNED_ANGLE = 40,
    REG_MOVING = 42,
    REG_BRAKE = 43,
    REG_REGISTERED = 44,
    REG_PRESENT_TEMPERATURE = 46,
    REG_SLEEP = 47,
    REG_PHOTO_SWITCHES = 48,
    REG_MOVE_WITHOUT_REFERENCE = 49,
};

/* Register 18 bits that concern the bus (§7.2). */
#define UNLOAD_REPORT_INSTRUCTION 0x20u
#define UNLOAD_REPORT_CHECKSUM 0x10u

enum reg_access { REG_ACCESS_R = 1, REG_ACCESS_W = 2, REG_ACCESS_RW = 3 };
enum reg_area { REG_AREA_NONE, REG_AREA_EE, REG_AREA_RAM };

/* Where a register's factory value comes from. */
enum reg_default {
    REG_DEF_CONST,        /* the descriptor's def */
    REG_DEF_MODEL,        /* board model number */
    REG_DEF_FIRMWARE,     /* SERVO_FW_VERSION of the build */
    REG_DEF_RETURN_DELAY, /* board return delay */
    REG_DEF_MAX_ANGLE,    /* board max angle in position units */
    REG_DEF_CURRENT,      /* board current limit */
    REG_DEF_COUNT
};

/* What a value means, for the docs and the host tools. */
enum reg_unit {
    REG_UNIT_NONE,
    REG_UNIT_POSITION,  /* register 13 x 0.1 degree */
    REG_UNIT_SPEED,     /* position units per second */
    REG_UNIT_DIR_SPEED, /* bit 15 direction, bits 0-14 position units per second */
    REG_UNIT_ACCEL,     /* 10 degree/s^2 */
    REG_UNIT_DELAY,     /* 500 us */
    REG_UNIT_CURRENT,   /* 0.1 A */
    REG_UNIT_TEMP,      /* bit 7 sign, bits 0-6 degree C */
    REG_UNIT_RES,       /* 0.1 degree */
};

#define REG_FLAG_SIGNED 0x01u /* two's complement on the wire */

/* Variant masks. */
#define REG_V(v) (1u << (v))
#define REG_V_ALL ((1u << VARIANT_COUNT) - 1u)
#define REG_V_B REG_V(VARIANT_BASE)
#define REG_V_NOT_B (REG_V_ALL & ~REG_V_B)
#define REG_V_WH (REG_V(VARIANT_WRIST) | REG_V(VARIANT_FINGER))
#define REG_V_NOT_WH (REG_V_ALL & ~REG_V_WH)

/* 4 bytes an entry instead of 8 (the table is in every image's flash): bit-fields, and
 * the default and the maximum in a byte each. No minimum in the table is above 1, no
 * default above 255, and every maximum is either a byte (1-byte registers) or ends in
 * 0xFF (2-byte registers: 0x7FFF, 0xFFFF), so max_code keeps the maximum's high byte
 * there; regs_max() gives it back. REG_ROW() in regs.c encodes a row and refuses to
 * compile one that does not fit. */
struct reg_desc {
    uint8_t size : 2;     /* 1 or 2 at the register's first address; 0 elsewhere */
    uint8_t access : 2;   /* enum reg_access */
    uint8_t area : 2;     /* enum reg_area */
    uint8_t min : 1;      /* the lowest value written: 0 or 1 */
    uint8_t variants : 5; /* REG_V_ masks of the five variants */
    uint8_t def_src : 3;  /* enum reg_default */
    uint8_t def;          /* factory value (REG_DEF_CONST) */
    uint8_t max_code;     /* the maximum (regs_max()) */
#if REGS_WITH_TEXT /* what only the docs and the host tools need: not in the images */
    uint8_t unit;
    uint8_t flags;
    const char *name; /* snake_case, as the host tools spell it */
    const char *doc;
#endif
};
/* The bit-fields' widths are set by hand: each must hold what it stores. */
_Static_assert(VARIANT_COUNT <= 5, "reg_desc.variants has a bit per variant");
_Static_assert(REG_DEF_COUNT <= 8, "reg_desc.def_src holds every enum reg_default");
_Static_assert(REG_ACCESS_RW <= 3 && REG_AREA_RAM <= 3, "reg_desc.access and .area: 2 bits");

/* The highest value a register takes (d describes its first address). */
static inline uint16_t regs_max(const struct reg_desc *d)
{
    return d->size == 2u ? (uint16_t)(((uint32_t)d->max_code << 8) | 0xFFu) : d->max_code;
}

/* The table, indexed by address. */
extern const struct reg_desc regs_table[REGS_SIZE];

/* The control table of one servo, in wire order (little-endian, as both the MCU and the
 * host are). Every 16-bit register sits at an even address, so it is one element of
 * half[]: one halfword load or store, never torn between its two bytes. */
struct regs {
    union {
        uint8_t mem[REGS_SIZE];
        uint16_t half[REGS_SIZE / 2u];
    };
    const struct board *board;
    uint8_t ee_changed; /* a writable EEPROM register changed value: the store has work */
    uint8_t ee_lazy;    /* one changed through regs_set_lazy(): the store may wait */
};

#if __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the control table is kept in wire order: little-endian targets only"
#endif

/* A host write of registers as the modules that act on it see it (write.h): the n bytes
 * written at addr, which addresses they cover, and what register 13 was before them (a
 * change of the unit rescales: §5). */
struct reg_write {
    uint8_t addr;
    uint8_t n;
    uint8_t old_resolution;
    const uint8_t *data;
    uint64_t touched; /* bit a: the write covers address a (regs_mask()) */
};

/* The addresses [addr, addr + n) as a mask, bit a for address a. */
uint64_t regs_mask(uint8_t addr, uint8_t n);

/* Does the write cover register reg (its first byte)? */
static inline bool reg_write_touches(const struct reg_write *w, uint8_t reg)
{
    return ((w->touched >> reg) & 1u) != 0u;
}

/* True if a register starts at addr and exists on this board's variant. */
bool regs_applicable(const struct board *b, uint8_t addr);

/* Factory value of the register starting at addr (0 for reserved addresses). */
uint16_t regs_default(const struct board *b, uint8_t addr);

/* Fill every register with its factory value (power-up: nothing marked as changed). */
void regs_init(struct regs *r, const struct board *b);

/* RESET: every register of an initialised table back to its factory value, through
 * regs_set() (so a changed EEPROM value is marked). */
void regs_reset(struct regs *r);

/* Value of a register of size bytes (1 or 2) stored little-endian at p. */
uint16_t regs_value(const uint8_t *p, uint8_t size);

/* Value of the register that starts at addr (1 or 2 bytes, little-endian). */
uint16_t regs_get(const struct regs *r, uint8_t addr);

/* Set the register that starts at addr, without validation (the core's own updates).
 * Marks the table when a writable EEPROM register gets a different value: every change
 * the store must keep goes through here. */
void regs_set(struct regs *r, uint8_t addr, uint16_t value);

/* Put a byte register's value in place without the table's rules: the bootloader's update
 * mode, which links no table, holds its three settings this way (loader.c). */
static inline void regs_put8(struct regs *r, uint8_t addr, uint8_t value)
{
    r->mem[addr] = value;
}

/* The same for a change that may reach the flash late (store_defer(): CUSTOM MOVE's
 * ramps on the base). */
void regs_set_lazy(struct regs *r, uint8_t addr, uint16_t value);

/* Main loop: did a writable EEPROM register change value since the last call? Clears
 * the mark. regs_take_ee_lazy() the same for regs_set_lazy(). */
bool regs_take_ee_changed(struct regs *r);
bool regs_take_ee_lazy(struct regs *r);

/* Copy count bytes from addr for a READ: reserved, write-only and not-applicable
 * addresses read as 0. The caller has checked addr + count <= REGS_SIZE. */
void regs_read(const struct regs *r, uint8_t addr, uint8_t count, uint8_t *out);

/* Validate a host write of n bytes at addr (§4.3): whole registers only, writable,
 * applicable, in range, and CW limit <= CCW limit afterwards. Returns true if valid. */
bool regs_write_valid(const struct regs *r, uint8_t addr, const uint8_t *data, uint8_t n);

/* True if v is within the range of the register that starts at addr. */
bool regs_in_range(uint8_t addr, uint16_t v);

/* The invariant a host can never break: the first register of r that holds a value its
 * descriptor refuses (a writable register out of range; for homing, the command nibble;
 * the CW limit above the CCW limit reports the CW limit), or REGS_SIZE if there is none.
 * Register 25 is a command and is not checked. */
uint8_t regs_first_invalid(const struct regs *r);

/* True if [addr, addr + n) touches a register of the given area. */
bool regs_touches_area(uint8_t addr, uint8_t n, uint8_t area);

/* Angle limits in force: both 0 means speed mode (and the base is always speed mode). */
bool regs_speed_mode(const struct regs *r);

/* The register-36 rule, the one place it is written: the present position is register
 * 36 where the variant has it (wrist, finger: 0..0xFFFF), else the turned angle (40,
 * signed). present.c writes it there; the goal, the tests and the harnesses read it. */
static inline uint8_t regs_position_addr(const struct board *b)
{
    return regs_applicable(b, REG_PRESENT_POSITION) ? (uint8_t)REG_PRESENT_POSITION
                                                    : (uint8_t)REG_TURNED_ANGLE;
}

/* The position the register at addr (regs_position_addr()) holds, raw as read. */
static inline int32_t regs_position_value(uint8_t addr, uint16_t raw)
{
    return addr == (uint8_t)REG_PRESENT_POSITION ? (int32_t)raw : (int32_t)(int16_t)raw;
}

/* The present position as the goal register counts it (regs_position_addr()). */
uint16_t regs_present_position(const struct regs *r);

/* The acceleration register of the variant (the deceleration follows it): 21 on the
 * base, 34 elsewhere (§5). */
uint8_t regs_ramp_addr(const struct board *b);

/* Goal clamped to the angle limits (unchanged in speed mode). */
uint16_t regs_clamp_goal(const struct regs *r, uint16_t goal);

#endif
