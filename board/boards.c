/* boards.c - the reference board of each variant (PROTOCOL.md §8). Model numbers, ranges
 * and current limits are this project's choices; the defaults of baud and return delay
 * are the spec's. */
#include <string.h>

#include "board.h"

const struct board board_base = {
    .name = "base", .variant = VARIANT_BASE, .model_number = BOARD_MODEL_BASE,
    .max_angle_ddeg = 0, .current_limit = 50, .default_baud = 115200,
    .return_delay = 8, .photo_switches = 0, .counts_per_rev = 16384,
    .supply_min_mv = 9000, .supply_max_mv = 15000, .homing_dps = 60, .homing_travel_deg = 800,
    .duty_per_amp = 166, /* 2 ohm at 12 V */
};

const struct board board_foot = {
    .name = "foot", .variant = VARIANT_FOOT, .model_number = BOARD_MODEL_FOOT,
    .max_angle_ddeg = 3600, .current_limit = 40, .default_baud = 9600,
    .return_delay = 16, .photo_switches = 0, .counts_per_rev = 16384,
    .supply_min_mv = 9000, .supply_max_mv = 15000, .homing_dps = 60, .homing_travel_deg = 800,
    .duty_per_amp = 166, /* 2 ohm at 12 V */
};

const struct board board_arm = {
    .name = "arm", .variant = VARIANT_ARM, .model_number = BOARD_MODEL_ARM,
    .max_angle_ddeg = 3600, .current_limit = 30, .default_baud = 9600,
    .return_delay = 16, .photo_switches = 1, .counts_per_rev = 16384,
    .supply_min_mv = 9000, .supply_max_mv = 15000, .homing_dps = 60, .homing_travel_deg = 800,
    .duty_per_amp = 166, /* 2 ohm at 12 V */
};

const struct board board_wrist = {
    .name = "wrist", .variant = VARIANT_WRIST, .model_number = BOARD_MODEL_WRIST,
    .max_angle_ddeg = 2700, .current_limit = 20, .default_baud = 9600,
    .return_delay = 16, .photo_switches = 1, .counts_per_rev = 16384,
    .supply_min_mv = 9000, .supply_max_mv = 15000, .homing_dps = 60, .homing_travel_deg = 800,
    .duty_per_amp = 166, /* 2 ohm at 12 V */
};

const struct board board_finger = {
    .name = "finger", .variant = VARIANT_FINGER, .model_number = BOARD_MODEL_FINGER,
    .max_angle_ddeg = 1800, .current_limit = 10, .default_baud = 9600,
    .return_delay = 16, .photo_switches = 1, .counts_per_rev = 16384,
    .supply_min_mv = 9000, .supply_max_mv = 15000, .homing_dps = 60, .homing_travel_deg = 800,
    .duty_per_amp = 166, /* 2 ohm at 12 V */
};

const struct board *const board_all[BOARD_COUNT] = {
    &board_base, &board_foot, &board_arm, &board_wrist, &board_finger,
};

const struct board *board_find(const char *name)
{
    for (uint32_t i = 0; i < BOARD_COUNT; i++)
        if (strcmp(board_all[i]->name, name) == 0)
            return board_all[i];
    return 0;
}
