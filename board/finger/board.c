/* board/finger/board.c - the reference finger board (PROTOCOL.md §8): what the core and the
 * protocol need of it (struct board, include/board.h). Its fittings come from
 * board_pins.h beside it, which the port builds from too, so the two cannot disagree: a
 * board whose core thought it had photo switches and whose port did not would never
 * find one while homing, and one the other way round would move unhomed. */
#include "board.h"
#include "board_pins.h"

const struct board board_finger = {
    .name = "finger", .variant = VARIANT_FINGER, .model_number = BOARD_MODEL_FINGER,
    .max_angle_ddeg = 1800, .current_limit = 10, .default_baud = 9600,
    .return_delay = 16, .photo_switches = BOARD_PHOTO, .fittings = BOARD_FITTINGS, .counts_per_rev = 16384,
    .supply_min_mv = 9000, .supply_max_mv = 15000, .homing_dps = 60, .homing_travel_deg = 800,
    .duty_per_amp = 166, /* 2 ohm at 12 V */
};
