/* model_parts.h - what each peripheral model (model_<part>.c) offers the bus (model.c):
 * reset, register read and write (offset within its block), the time of its next event
 * and catching up with model.now. Internal to the models. */
#ifndef PORT_MODEL_PARTS_H
#define PORT_MODEL_PARTS_H

#include <stdint.h>

#include "model.h"

#define PART(name)                                                                       \
    void name##_reset(uint8_t why);                                                      \
    uint32_t name##_read(uint32_t off, uint32_t bytes);                                   \
    void name##_write(uint32_t off, uint32_t value, uint32_t bytes);                      \
    uint64_t name##_next(void);                                                          \
    void name##_sync(void);

PART(rcc)
PART(fpec)
PART(gpio)
PART(usart)
PART(iwdg)
PART(cpu)
PART(tim)
PART(adc)

#undef PART

/* The flash array (writes and the driver's reads go through the FPEC), F_SIZE. */
uint32_t fpec_array_read(uint32_t addr, uint32_t bytes);
void fpec_array_write(uint32_t addr, uint32_t value, uint32_t bytes);
uint32_t fpec_wait_states(void);

/* DMA1 channel 1 registers (model_adc.c). */
uint32_t dma_read(uint32_t off, uint32_t bytes);
void dma_write(uint32_t off, uint32_t value, uint32_t bytes);

/* GPIO tells the USART when its driver enable changes; the USART asks GPIO about its
 * pins. */
void usart_de_changed(bool high);

/* The USART1 interrupt line, SysTick pending (model_cpu.c delivers them). */
bool usart_irq(void);
void cpu_deliver(void);

/* TIM3's next TRGO rising edge after tick t (MODEL_NEVER: none). */
uint64_t tim3_trgo_after(uint64_t t);

/* Ticks per CPU cycle now. */
uint64_t model_cycle_ticks(void);

/* Is the peripheral clock of bit `bit` of enable register `reg` (0 AHB, 1 APB2, 2 APB1)
 * on? */
bool rcc_clock_on(uint32_t reg, uint32_t bit);

#endif
