/* uart.c - USART1, half duplex through an RS485 transceiver: every received byte goes
 * to servo_rx_isr_at() from the interrupt; a reply is sent from the caller's buffer by
 * the same interrupt (TXE, then TC), with the driver enable asserted from the first byte
 * until the last stop bit has left (TC). While sending, received bytes are the echo of
 * our own (single-wire or RE-enabled transceivers) and are dropped.
 *
 * The interrupt handler and everything it calls live in RAM, so reception goes on at
 * any baud while the store erases a flash page (the CPU stalls on flash reads). */
#include "hal_stm32f1.h"
#include "servo.h"
#include "stm32f1_regs.h"

/* Transmit steps, with USART1's interrupt masked or from within it: next byte while
 * TXE, then release the driver on TC. Reading SR before writing DR is half of clearing
 * TC, so TC is only seen once the last byte has left (an emulator that sends at once
 * shows it at once, and the loop finishes in one call). */
static RAMFUNC void tx_step(struct hal *h)
{
    for (;;) {
        uint32_t sr = REG_READ(USART1->sr), cr1 = REG_READ(USART1->cr1);
        if ((cr1 & USART_CR1_TXEIE) && (sr & USART_SR_TXE)) {
            REG_WRITE(USART1->dr, h->tx_buf[h->tx_pos++]);
            if (h->tx_pos == h->tx_len)
                REG_WRITE(USART1->cr1, (cr1 & ~USART_CR1_TXEIE) | USART_CR1_TCIE);
        } else if ((cr1 & USART_CR1_TCIE) && (sr & USART_SR_TC)) {
            REG_WRITE(USART1->cr1, cr1 & ~USART_CR1_TCIE);
            gpio_write(BOARD_PIN_RS485_DE, false);
            h->tx_active = 0;
            return;
        } else {
            return;
        }
    }
}

/* The arrival time of a byte, in this interrupt: hal_clock_us() without its pending-tick
 * case, which cannot arise here: SysTick outranks USART1 (PRIO_SYSTICK), so a wrap is
 * serviced at once, and a tick count that moved while the counter was read is read
 * again. */
static inline uint32_t rx_clock_us(const struct hal *h)
{
    uint32_t base, v;
    do {
        base = h->tick_us;
        v = REG_READ(SYSTICK->cvr);
    } while (base != h->tick_us);
    return base + (h->tick_reload - v) / h->cycles_per_us;
}

RAMFUNC void usart1_handler(void)
{
    struct hal *h = &hal_stm32;
    uint32_t sr = REG_READ(USART1->sr);
    if (sr & (USART_SR_RXNE | USART_SR_ORE)) {
        /* Reading DR after SR clears RXNE and the error flags (ORE, FE, NE, PE). */
        uint8_t byte = (uint8_t)REG_READ(USART1->dr);
        if (sr & USART_SR_ORE)
            h->rx_overruns++; /* the byte after this one was lost (DR keeps this one) */
        if (sr & USART_SR_FE)
            h->rx_errors++; /* a broken byte (or a break): drop it */
        else if (!h->tx_active) /* RXNE comes mid stop bit: the byte ends half a bit
                                  * later, and the return delay (§2) counts from there
                                  * (with delay 0, never over the host's stop bit) */
            servo_rx_isr_at(h->servo, byte, rx_clock_us(h) + h->rx_half_bit_us);
    }
    if (h->tx_active) /* TXEIE and TCIE are only ever on while sending */
        tx_step(h);
}

void uart_init(struct hal *h)
{
    (void)h;
    REG_SET(RCC->apb2enr, RCC_APB2ENR_USART1EN);
    gpio_write(BOARD_PIN_UART_RX, true); /* pull-up: an idle line reads high */
    gpio_mode(BOARD_PIN_UART_RX, GPIO_IN_PULL);
    gpio_mode(BOARD_PIN_UART_TX, GPIO_AF_PP_50MHZ);
    REG_WRITE(USART1->cr2, 0); /* 1 stop bit */
    REG_WRITE(USART1->cr3, 0);
    REG_WRITE(USART1->brr, 0xFFFFu); /* the core sets the baud in servo_init() */
    REG_WRITE(USART1->cr1, USART_CR1_UE | USART_CR1_TE | USART_CR1_RE);
}

void uart_start(struct hal *h, struct servo *s)
{
    h->servo = s;
    (void)REG_READ(USART1->sr);
    (void)REG_READ(USART1->dr); /* anything received before the core was ready */
    REG_WRITE(NVIC->ip[IRQ_USART1], PRIO_USART1);
    REG_SET(USART1->cr1, USART_CR1_RXNEIE);
    REG_WRITE(NVIC->iser[IRQ_USART1 / 32u], 1u << (IRQ_USART1 % 32u));
}

/* USART1 runs from PCLK2 with 16x oversampling: BRR = PCLK2 / baud, rounded, and at
 * least 16 (USARTDIV = BRR / 16 >= 1: the fastest rate is PCLK2 / 16, 500 kBd on the
 * 8 MHz HSI). Not inlined: its two callers each got a copy of the division and the
 * clamps (24 B). */
__attribute__((noinline)) static uint32_t brr_for(const struct hal *h, uint32_t baud)
{
    uint32_t div = (h->pclk2_hz + baud / 2u) / baud;
    return div < 16u ? 16u : div > 0xFFFFu ? 0xFFFFu : div;
}

void hal_uart_set_baud(struct hal *h, uint32_t baud)
{
    REG_WRITE(USART1->brr, brr_for(h, baud));
    h->rx_half_bit_us = 500000u / baud;
}

/* The rate BRR gives: PCLK2 / BRR (RM0008 §27.3.4). */
uint32_t hal_uart_baud_achieved(const struct hal *h, uint32_t baud)
{
    return h->pclk2_hz / brr_for(h, baud);
}

void hal_uart_send(struct hal *h, const uint8_t *buf, uint16_t len)
{
    if (len == 0u)
        return;
    uint32_t irq = hal_irq_save(h);
    h->tx_buf = buf;
    h->tx_len = len;
    h->tx_pos = 0;
    h->tx_active = 1;
    gpio_write(BOARD_PIN_RS485_DE, true);
    REG_SET(USART1->cr1, USART_CR1_TXEIE); /* the interrupt writes the first byte at once */
    hal_irq_restore(h, irq);
}

/* Also steps the transmission from here, masked: an emulator without TXE/TC interrupts
 * (QEMU 7.2's STM32 USART raises only RXNE) sends from here. On silicon the interrupt
 * has always been first and this finds nothing to do. */
bool hal_uart_tx_busy(struct hal *h)
{
    if (!h->tx_active)
        return false;
    uint32_t irq = hal_irq_save(h);
    tx_step(h);
    hal_irq_restore(h, irq);
    return h->tx_active != 0u;
}
