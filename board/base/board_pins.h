/* board/base/board_pins.h - the reference base board (chassis wheel, 5 A limit): which fittings
 * of the shared reference PCB (board/ref_pcb.h) it carries. board_base in board.c beside it
 * holds its model number, range and limits, and takes BOARD_PHOTO from here. */
#ifndef BOARD_PINS_H
#define BOARD_PINS_H

#define BOARD_POSITION_POT 0 /* quadrature encoder */
#define BOARD_PHOTO 0        /* homing photo switches not fitted */
#define BOARD_CURRENT_MA_FS 8250u /* mA at ADC full scale: 20 mOhm shunt x 20 */

#include "../ref_pcb.h"

#endif
