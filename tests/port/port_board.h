/* port_board.h - the reference board's analog side for the ADC model (ref_pcb.h):
 * a 12 V supply through its divider, 25 C at the temperature sensor, the potentiometer
 * mid-scale, and the shunt amplifier: port_shunt_ma while the bridge drives (TIM3's
 * CH1 or CH2 reference active), nothing while both are low (the current decays through
 * the bridge, not the low-side shunt). */
#ifndef PORT_BOARD_H
#define PORT_BOARD_H

#include <stdint.h>

#include "hal_stm32f1.h"
#include "model.h"

static uint32_t port_shunt_ma; /* the winding current during the on-time */
static uint32_t port_supply_mv = 12000u;

static inline uint16_t port_counts(uint32_t mv_or_ma, uint32_t full_scale)
{
    uint32_t c = (mv_or_ma * 4096u + full_scale / 2u) / full_scale;
    return (uint16_t)(c > 4095u ? 4095u : c);
}

static inline uint16_t port_board_analog(uint8_t channel, uint64_t tick)
{
    switch (channel) {
    case BOARD_ADC_CURRENT: {
        bool on = model_tim3_ref(1, tick) || model_tim3_ref(2, tick);
        return on ? port_counts(port_shunt_ma, BOARD_CURRENT_MA_FS) : 0u;
    }
    case BOARD_ADC_SUPPLY:
        return port_counts(port_supply_mv, BOARD_SUPPLY_MV_FS);
    case BOARD_ADC_TEMP:
        return port_counts(BOARD_TEMP_MV_AT_0C + 250u * BOARD_TEMP_UV_PER_DC / 1000u, 3300u);
    default:
        return 2048u; /* the potentiometer, mid-scale */
    }
}

#endif
