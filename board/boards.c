/* boards.c - every reference board (board/<name>/board.c each, PROTOCOL.md §8), in the
 * order of the one board list (cmake/boards.cmake, include/board_list.h). Model numbers,
 * ranges and current limits are this project's choices; the defaults of baud and return
 * delay are the spec's. */
#include <string.h>

#include "board.h"

const struct board *const board_all[BOARD_COUNT] = BOARD_ALL_INIT;

const struct board *board_find(const char *name)
{
    for (uint32_t i = 0; i < BOARD_COUNT; i++)
        if (strcmp(board_all[i]->name, name) == 0)
            return board_all[i];
    return 0;
}
