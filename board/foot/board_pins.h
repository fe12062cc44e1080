/* board/foot/board_pins.h - the reference foot board (4 A limit): which fittings
 * of the shared reference PCB (board/ref_pcb.h) it carries. board_foot in board.c beside it
 * holds its model number, range and limits, and takes BOARD_PHOTO from here. */
#ifndef BOARD_PINS_H
#define BOARD_PINS_H

#define BOARD_POSITION_POT 0 /* quadrature encoder */
#define BOARD_PHOTO 0        /* homing photo switches not fitted */
#define BOARD_CURRENT_MA_FS 6600u /* mA at ADC full scale: 25 mOhm shunt x 20 */

#include "../ref_pcb.h"

#endif
