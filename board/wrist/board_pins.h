/* board/wrist/board_pins.h - the reference wrist board (2 A limit): what it fits on
 * the shared reference PCB (board/ref_pcb.h). board_wrist in board/boards.c holds its model
 * number, range and limits. */
#ifndef BOARD_PINS_H
#define BOARD_PINS_H

#include "../ref_pcb.h"

/* Position: potentiometer on the output shaft, ADC1 channel 0 (PA0); its electrical
 * span over the ADC full scale sets the counts (struct board counts_per_rev per turn). */
#define BOARD_POSITION_POT 1
#define BOARD_ADC_POT 0u
#define BOARD_POT_SPAN_DDEG 3000u /* 300 degrees from 0 V to 3.3 V */
#define BOARD_POT_INVERT 0

/* Current shunt amplifier (x 20) on the shared ADC channel. */
#define BOARD_CURRENT_MA_FS 3300u /* mA at ADC full scale: 50 mOhm shunt x 20 */

/* Homing photo switches fitted. */
#define BOARD_PHOTO 1
#define BOARD_PIN_PHOTO1 BOARD_REF_PIN_PHOTO1
#define BOARD_PIN_PHOTO2 BOARD_REF_PIN_PHOTO2
#define BOARD_PHOTO_ACTIVE_HIGH 1

#endif
