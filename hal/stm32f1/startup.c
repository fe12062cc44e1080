/* startup.c - reset: vector table, RAM set-up, then main(); the one fault path (outputs
 * safe, system reset) and hal_restart(). The vector table is copied to RAM at boot so
 * that interrupts keep being taken while a flash erase stalls every flash read. The
 * bootloader and the application share this file; each main() sets the clock up (the
 * bootloader only once it knows it stays, so the application starts from the reset
 * clock). */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "hal_stm32f1.h"
#include "stm32f1_regs.h"

/* The register maps against RM0008's offsets. */
_Static_assert(offsetof(struct nvic_regs, icer) == 0x80, "NVIC ICER");
_Static_assert(offsetof(struct nvic_regs, ip) == 0x300, "NVIC IPR");
_Static_assert(offsetof(struct scb_regs, shp) == 0x18, "SCB SHPR");
_Static_assert(offsetof(struct rcc_regs, csr) == 0x24, "RCC CSR");
_Static_assert(offsetof(struct flash_regs, wrpr) == 0x20, "FLASH WRPR");
_Static_assert(offsetof(struct tim_regs, ccr1) == 0x34, "TIM CCR1");
_Static_assert(offsetof(struct adc_regs, dr) == 0x4C, "ADC DR");
_Static_assert(offsetof(struct dma_regs, ch[1]) == 0x1C, "DMA channel 2");
_Static_assert(offsetof(struct usart_regs, gtpr) == 0x18, "USART GTPR");

int main(void);

/* Linker script symbols (board/stm32f103x8.ld). */
extern uint32_t _sidata[], _sdata[], _edata[], _sbss[], _ebss[], _estack[];

typedef void (*vector)(void);

/* Flash copy of the vector table: what the core reads at reset. */
/* The bootloader enables no interrupt past USART1's, so its table ends there. */
#ifdef SERVO_BOOTLOADER
#define VECTORS (16u + IRQ_USART1 + 1u)
#else
#define VECTORS VECTORS_F103
#endif

__attribute__((section(".isr_vector"), used)) static const vector vectors[VECTORS] = {
    [0] = (vector)(uintptr_t)_estack,
    [1] = reset_handler,
    [2] = fault_handler,  /* NMI: the clock security system saw the crystal fail */
    [3] = fault_handler,  /* HardFault */
    [4] = fault_handler,  /* MemManage */
    [5] = fault_handler,  /* BusFault */
    [6] = fault_handler,  /* UsageFault */
    [11] = fault_handler, /* SVCall */
    [12] = fault_handler, /* DebugMon */
    [14] = fault_handler, /* PendSV */
    [15] = systick_handler,
    [16 + IRQ_USART1] = usart1_handler,
};

/* The live table (VTOR): in RAM, at the start of RAM (the linker script puts it there),
 * aligned to its size rounded up to a power of two. */
__attribute__((section(".ram_vectors"), aligned(256)))
static uint32_t ram_vectors[VECTORS];

void reset_handler(void)
{
    /* .data holds the RAM functions too: copy, then clear .bss. */
    memcpy(_sdata, _sidata, (size_t)((char *)_edata - (char *)_sdata));
    memset(_sbss, 0, (size_t)((char *)_ebss - (char *)_sbss));
    /* Unused vectors (left 0 above) go to the fault path too. */
    for (uint32_t i = 0; i < VECTORS; i++)
        ram_vectors[i] = (uint32_t)(uintptr_t)(vectors[i] ? vectors[i] : fault_handler);
    ram_vectors[0] = (uint32_t)(uintptr_t)_estack;
    REG_WRITE(SCB->vtor, (uint32_t)(uintptr_t)ram_vectors);
    CPU_DSB();
    CPU_ISB();
    main();
    fault_reset();
}

/* Every unexpected exception: a servo that cannot know its state stops the motor and
 * starts again (the independent watchdog would do the same, later). */
void fault_handler(void)
{
    fault_reset();
}

/* The core's restart (an update staged, or installed): the same way out as a fault. The
 * bootloader runs next. */
void hal_restart(struct hal *h)
{
    (void)h;
    fault_reset();
}

void fault_reset(void)
{
    __asm volatile("cpsid i" ::: "memory");
    gpio_write(BOARD_PIN_DRIVER_EN, false);
    gpio_write(BOARD_PIN_RS485_DE, false);
    CPU_DSB();
    REG_WRITE(SCB->aircr, SCB_AIRCR_VECTKEY | SCB_AIRCR_SYSRESETREQ);
    CPU_DSB();
    for (;;) {
    }
}
