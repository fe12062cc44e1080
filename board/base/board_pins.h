/* board/base/board_pins.h - the reference base board (chassis wheel, 5 A limit): what it fits on
 * the shared reference PCB (board/ref_pcb.h). board_base in board/boards.c holds its model
 * number, range and limits. */
#ifndef BOARD_PINS_H
#define BOARD_PINS_H

#include "../ref_pcb.h"

/* Position: quadrature encoder on TIM2 CH1/CH2 (encoder mode 3, 4 counts per line);
 * struct board counts_per_rev = lines x 4 x gear ratio. */
#define BOARD_POSITION_POT 0
#define BOARD_PIN_ENC_A PIN('A', 0) /* TIM2_CH1 */
#define BOARD_PIN_ENC_B PIN('A', 1) /* TIM2_CH2 */
#define BOARD_ENCODER_INVERT 0

/* Current shunt amplifier (x 20) on the shared ADC channel. */
#define BOARD_CURRENT_MA_FS 8250u /* mA at ADC full scale: 20 mOhm shunt x 20 */

/* No homing photo switches on this variant. */
#define BOARD_PHOTO 0

#endif
