/* hal_host.c - HAL on the host: virtual clock and a logging UART. */
#include <string.h>

#include "hal_host.h"
#include "image.h"

void hal_host_init(struct hal *h)
{
    memset(h, 0, sizeof *h);
    h->now_us = HAL_HOST_CLOCK_START;
    h->baud = 9600;
    flash_sim_init(&h->flash);
    motor_sim_init(&h->motor, HAL_HOST_COUNTS_PER_REV);
    h->supply_mv = 12000;
    h->temperature_dc = 250;
    h->power_reset = true;
    /* The host simulates every fitting; a test takes one away to model a port without. */
    h->capabilities = HAL_CAP_PHOTO | HAL_CAP_TERMINATOR | HAL_CAP_ENCODER | HAL_CAP_POT;
}

uint8_t hal_capabilities(struct hal *h)
{
    return h->capabilities;
}

const uint8_t *hal_uid(struct hal *h)
{
    return h->uid;
}

void hal_host_reboot(struct hal *h)
{
    h->baud = 9600;
    h->tx_active = false;
    h->irq_depth = 0;
    flash_sim_power_on(&h->flash);
    motor_sim_advance(&h->motor, h->now_us);
    h->motor.enabled = false; /* a reset leaves the bridge off until the core says */
    h->motor.duty = 0;
    h->termination = false;
    h->stalled = false; /* a reset ends an erase */
    h->power_reset = !h->restart_requested; /* hal_restart() or the watchdog model, or power */
    h->restart_requested = false;
    h->watchdog_started = false;
}

void hal_host_program_app(struct hal *h, const uint8_t *img, uint32_t len)
{
    for (uint32_t p = 0; p < HAL_SLOT_PAGES; p++) {
        uint8_t *page = h->flash.mem[HAL_PAGE_APP + p];
        memset(page, 0xFF, HAL_FLASH_PAGE_BYTES);
        uint32_t at = p * HAL_FLASH_PAGE_BYTES;
        if (at < len)
            memcpy(page, &img[at], len - at < HAL_FLASH_PAGE_BYTES ? len - at : HAL_FLASH_PAGE_BYTES);
    }
}

uint32_t hal_host_byte_start(uint32_t t0, uint32_t baud, uint32_t i)
{
    return t0 + (uint32_t)((uint64_t)i * 10000000u / baud);
}

uint32_t hal_host_byte_end(uint32_t t0, uint32_t baud, uint32_t i)
{
    return t0 + (uint32_t)(((uint64_t)(i + 1u) * 10000000u + baud - 1u) / baud);
}

const struct hal_tx_byte *hal_host_tx(const struct hal *h, uint32_t i)
{
    return &h->log[i % HAL_HOST_TX_LOG];
}

uint32_t hal_clock_us(struct hal *h)
{
    return h->now_us;
}

void hal_uart_set_baud(struct hal *h, uint32_t baud)
{
    h->baud = baud;
    h->baud_sets++;
}

/* As the STM32's USART would on uart_clock_hz: the divider rounded, 16 at least. */
uint32_t hal_uart_baud_achieved(const struct hal *h, uint32_t baud)
{
    if (h->uart_clock_hz == 0u)
        return baud;
    uint32_t div = (h->uart_clock_hz + baud / 2u) / baud;
    return h->uart_clock_hz / (div < 16u ? 16u : div > 0xFFFFu ? 0xFFFFu : div);
}

void hal_uart_send(struct hal *h, const uint8_t *buf, uint16_t len)
{
    uint32_t t0 = h->now_us;
    for (uint16_t i = 0; i < len; i++) {
        struct hal_tx_byte *b = &h->log[h->log_len++ % HAL_HOST_TX_LOG];
        b->byte = buf[i];
        b->baud = h->baud;
        b->start_us = hal_host_byte_start(t0, h->baud, i);
        b->end_us = hal_host_byte_end(t0, h->baud, i);
    }
    h->tx_end_us = hal_host_byte_end(t0, h->baud, (uint32_t)len - 1u);
    h->tx_active = len > 0;
    h->sends++;
}

bool hal_uart_tx_busy(struct hal *h)
{
    if (h->tx_active && (int32_t)(h->now_us - h->tx_end_us) >= 0)
        h->tx_active = false;
    return h->tx_active;
}

uint32_t hal_irq_save(struct hal *h)
{
    return (uint32_t)h->irq_depth++;
}

void hal_irq_restore(struct hal *h, uint32_t state)
{
    h->irq_depth = (int32_t)state;
}

const uint8_t *hal_flash_page(struct hal *h, uint8_t p)
{
    return flash_sim_page(&h->flash, p);
}

bool hal_flash_erase(struct hal *h, uint8_t p)
{
    if (h->erase_stall_us) {
        h->stalled = true;
        h->stall_until_us = h->now_us + h->erase_stall_us;
    }
    return flash_sim_erase(&h->flash, p);
}

bool hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value)
{
    return flash_sim_program(&h->flash, p, off, value);
}

void hal_restart(struct hal *h)
{
    h->restart_requested = true;
}

void hal_motor_enable(struct hal *h, bool on)
{
    motor_sim_advance(&h->motor, h->now_us);
    h->motor.enabled = on;
}

void hal_motor_drive(struct hal *h, int16_t duty)
{
    motor_sim_advance(&h->motor, h->now_us);
    h->motor.duty = duty;
}

int32_t hal_motor_position(struct hal *h)
{
    motor_sim_advance(&h->motor, h->now_us);
    return motor_sim_counts(&h->motor);
}

uint16_t hal_motor_current_ma(struct hal *h)
{
    motor_sim_advance(&h->motor, h->now_us);
    double ma = h->motor.current * 1000.0;
    ma = (ma < 0 ? -ma : ma) + h->current_extra_ma;
    return (uint16_t)(ma > 65535.0 ? 65535.0 : ma);
}

uint16_t hal_supply_mv(struct hal *h)
{
    return h->supply_mv;
}

int16_t hal_temperature_dc(struct hal *h)
{
    return h->temperature_dc;
}

void hal_host_attach_board(struct hal *h, const struct board *b)
{
    if (!b->photo_switches)
        return;
    h->photo_sim = true;
    h->sw1_deg = 0.0;
    h->sw2_deg = b->variant == VARIANT_ARM ? 420.0 : b->max_angle_ddeg / 10.0;
    h->motor.theta = 90.0 / 57.29577951308232;
}

uint8_t hal_photo_switches(struct hal *h)
{
    if (!h->photo_sim)
        return h->photo;
    motor_sim_advance(&h->motor, h->now_us);
    double deg = h->motor.theta * 57.29577951308232;
    bool up = h->sw2_deg > h->sw1_deg;
    uint8_t bits = 0;
    if (up ? deg <= h->sw1_deg : deg >= h->sw1_deg)
        bits |= 1u;
    if (up ? deg >= h->sw2_deg : deg <= h->sw2_deg)
        bits |= 2u;
    return bits;
}

void hal_rs485_termination(struct hal *h, bool on)
{
    h->termination = on;
}

void hal_watchdog_start(struct hal *h)
{
    h->watchdog_started = true;
}

void hal_watchdog_feed(struct hal *h)
{
    h->watchdog_feeds++;
}

bool hal_reset_by_power(struct hal *h)
{
    return h->power_reset;
}
