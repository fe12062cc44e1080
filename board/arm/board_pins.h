/* board/arm/board_pins.h - the reference arm board (3 A limit): which fittings
 * of the shared reference PCB (board/ref_pcb.h) it carries. board_arm in board.c beside it
 * holds its model number, range and limits, and takes BOARD_PHOTO from here. */
#ifndef BOARD_PINS_H
#define BOARD_PINS_H

#define BOARD_POSITION_POT 0 /* quadrature encoder */
#define BOARD_PHOTO 1        /* homing photo switches fitted */
#define BOARD_CURRENT_MA_FS 5500u /* mA at ADC full scale: 30 mOhm shunt x 20 */

#include "../ref_pcb.h"

#endif
