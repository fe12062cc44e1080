/* board.h - per-variant board configuration: what the control table's defaults and the
 * safety limits depend on. The MCU image links one board (chosen by CMake's BOARD);
 * the host links all of them so one process can simulate a mixed bus. */
#ifndef BOARD_H
#define BOARD_H

#include <stdint.h>

#include "board_list.h" /* BOARD_COUNT and the boards, from cmake/boards.cmake */

/* The motor variants of PROTOCOL.md §8. */
enum variant {
    VARIANT_BASE,   /* B: chassis wheel, speed mode always */
    VARIANT_FOOT,   /* F */
    VARIANT_ARM,    /* A */
    VARIANT_WRIST,  /* W */
    VARIANT_FINGER, /* H */
    VARIANT_COUNT
};

/* Model numbers (registers 0-1). Here as constants because the STM32 image's info block
 * (image.h) states its board's model in a static initializer. */
#define BOARD_MODEL_BASE 0x5201u
#define BOARD_MODEL_FOOT 0x5202u
#define BOARD_MODEL_ARM 0x5203u
#define BOARD_MODEL_WRIST 0x5204u
#define BOARD_MODEL_FINGER 0x5205u

struct board {
    const char *name;          /* its folder's name, board/<name>/ (cmake/boards.cmake) */
    uint8_t variant;           /* enum variant */
    uint16_t model_number;     /* registers 0-1 */
    uint16_t max_angle_ddeg;   /* mechanical range in 0.1 degree; 0 = continuous */
    uint8_t current_limit;     /* register 12 default, 0.1 A */
    uint32_t default_baud;     /* what register 4 = 0 means */
    uint8_t return_delay;      /* register 5 default, x 500 us */
    uint8_t photo_switches;    /* 1 if the board has the two homing switches: BOARD_PHOTO of
                                * its board_pins.h, which the port builds from too */
    uint8_t fittings;          /* HAL_CAP_* (hal.h) it needs: BOARD_FITTINGS of its
                                * board_pins.h */
    uint32_t counts_per_rev;   /* position sensor counts per output turn */
    uint16_t supply_min_mv;    /* under-voltage below this */
    uint16_t supply_max_mv;    /* over-voltage above this */
    uint16_t homing_dps;       /* homing speed, degrees/s */
    uint16_t homing_travel_deg; /* a switch not found within this travel fails homing */
    uint16_t duty_per_amp;     /* winding resistance / supply x 1000: duty that drives 1 A
                                * into a motor at rest (current limiting) */
};

/* All the reference boards (board_<name> each, declared in board_list.h) in the order of
 * cmake/boards.cmake: host tools, tests and fuzzers iterate board_all. */
extern const struct board *const board_all[BOARD_COUNT];

/* The reference board of a variant name ("arm"), or 0 if there is none. */
const struct board *board_find(const char *name);

#endif
