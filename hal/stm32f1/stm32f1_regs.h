/* stm32f1_regs.h - the STM32F103 registers this port uses, written from
 * the reference manual RM0008 and the Cortex-M3 technical reference; nothing else. One
 * struct per peripheral block, laid out as the manual's register map; bit names follow
 * the manual so a reader can check them against it. */
#ifndef STM32F1_REGS_H
#define STM32F1_REGS_H

#include <stdint.h>

typedef volatile uint32_t reg32;

/* Every read and write of a peripheral register, and of the flash array by the FPEC
 * code, goes through REG_READ and REG_WRITE; on the MCU they are the plain volatile
 * accesses. The host build of the drivers defines them first (tests/port/model.h,
 * included ahead of everything) to hand each access, with its address and width, to
 * register models that give it RM0008's side effects. The CPU_ instructions below are
 * overridable the same way. Nothing else changes for the host. */
#ifndef REG_READ
#define REG_READ(r) (r)
#define REG_WRITE(r, v) ((void)((r) = (v)))
#endif
#define REG_SET(r, bits) REG_WRITE(r, REG_READ(r) | (bits))    /* read, OR, write */
#define REG_CLEAR(r, bits) REG_WRITE(r, REG_READ(r) & ~(bits)) /* read, AND NOT, write */

/* Cortex-M3 instructions the drivers use (ARMv7-M ARM). */
#ifndef CPU_DSB
#define CPU_DSB() __asm volatile("dsb" ::: "memory")
#define CPU_ISB() __asm volatile("isb" ::: "memory")
#define CPU_WFI() __asm volatile("wfi")
/* BASEPRI: read; raise to at least v (never lowers it); write. */
#define CPU_BASEPRI_GET(out) __asm volatile("mrs %0, basepri" : "=r"(out))
#define CPU_BASEPRI_MAX(v) __asm volatile("msr basepri_max, %0" ::"r"(v) : "memory")
#define CPU_BASEPRI_SET(v) __asm volatile("msr basepri, %0" ::"r"(v) : "memory")
/* Main stack pointer to sp, then branch to pc, with no stack use between the two. */
#define CPU_JUMP(sp, pc) __asm volatile("msr msp, %0\n\tbx %1" ::"r"(sp), "r"(pc) : "memory")
#endif

/* ---- Cortex-M3 system control space (ARMv7-M ARM, Cortex-M3 TRM) ---- */
struct systick_regs {
    reg32 csr, rvr, cvr, calib;
};
#define SYSTICK ((struct systick_regs *)0xE000E010u)
#define SYSTICK_CSR_ENABLE (1u << 0)
#define SYSTICK_CSR_TICKINT (1u << 1)
#define SYSTICK_CSR_CLKSOURCE (1u << 2) /* 1: processor clock (HCLK) */

struct scb_regs {
    reg32 cpuid, icsr, vtor, aircr, scr, ccr;
    volatile uint8_t shp[12]; /* system handler priorities, exceptions 4..15 */
};
#define SCB ((struct scb_regs *)0xE000ED00u)
#define SCB_ICSR_PENDSTSET (1u << 26)
#define SCB_AIRCR_VECTKEY (0x05FAu << 16)
#define SCB_AIRCR_SYSRESETREQ (1u << 2)
#define SCB_SHP_SYSTICK 11u /* shp[15 - 4] */

struct nvic_regs {
    reg32 iser[8];
    uint32_t reserved0[24];
    reg32 icer[8];
    uint32_t reserved1[24];
    reg32 ispr[8];
    uint32_t reserved2[24];
    reg32 icpr[8];
    uint32_t reserved3[88];
    volatile uint8_t ip[240];
};
#define NVIC ((struct nvic_regs *)0xE000E100u)

/* STM32F1 implements the top 4 bits of each priority byte. */
#define IRQ_USART1 37u
#define VECTORS_F103 (16u + 43u) /* medium density: 43 peripheral interrupts */

/* ---- Reset and clock control (RM0008 §7.3) ---- */
struct rcc_regs {
    reg32 cr, cfgr, cir, apb2rstr, apb1rstr, ahbenr, apb2enr, apb1enr, bdcr, csr;
};
#define RCC ((struct rcc_regs *)0x40021000u)
#define RCC_CSR_RMVF (1u << 24)
#define RCC_CSR_SFTRSTF (1u << 28)
#define RCC_CSR_IWDGRSTF (1u << 29)
#define RCC_CSR_WWDGRSTF (1u << 30)
#define RCC_CR_HSION (1u << 0)
#define RCC_CR_HSIRDY (1u << 1)
#define RCC_CR_HSEON (1u << 16)
#define RCC_CR_HSERDY (1u << 17)
#define RCC_CR_HSEBYP (1u << 18)
#define RCC_CR_CSSON (1u << 19)
#define RCC_CR_PLLON (1u << 24)
#define RCC_CR_PLLRDY (1u << 25)
#define RCC_CFGR_SW_HSI (0u << 0)
#define RCC_CFGR_SW_PLL (2u << 0)
#define RCC_CFGR_SW_MASK (3u << 0)
#define RCC_CFGR_SWS_PLL (2u << 2)
#define RCC_CFGR_SWS_MASK (3u << 2)
#define RCC_CFGR_PPRE1_DIV2 (4u << 8)  /* APB1 = HCLK / 2 */
#define RCC_CFGR_ADCPRE_SHIFT 14u      /* 0: /2, 1: /4, 2: /6, 3: /8 */
#define RCC_CFGR_PLLSRC_HSE (1u << 16) /* 0: HSI / 2 */
#define RCC_CFGR_PLLMUL(m) ((uint32_t)((m) - 2u) << 18) /* x2 .. x16 */
#define RCC_CIR_CSSC (1u << 23)
#define RCC_AHBENR_DMA1EN (1u << 0)
#define RCC_APB2ENR_IOPAEN (1u << 2)
#define RCC_APB2ENR_IOPBEN (1u << 3)
#define RCC_APB2ENR_IOPCEN (1u << 4)
#define RCC_APB2ENR_ADC1EN (1u << 9)
#define RCC_APB2ENR_USART1EN (1u << 14)
#define RCC_APB1ENR_TIM2EN (1u << 0)
#define RCC_APB1ENR_TIM3EN (1u << 1)

/* ---- Flash memory interface (RM0008 §3.3.3; PM0075 for program/erase) ---- */
struct flash_regs {
    reg32 acr, keyr, optkeyr, sr, cr, ar, reserved, obr, wrpr;
};
#define FLASH ((struct flash_regs *)0x40022000u)
#define FLASH_ACR_LATENCY(ws) ((uint32_t)(ws)) /* 0: <= 24 MHz, 1: <= 48, 2: <= 72 */
#define FLASH_ACR_PRFTBE (1u << 4)
#define FLASH_KEY1 0x45670123u
#define FLASH_KEY2 0xCDEF89ABu
#define FLASH_SR_BSY (1u << 0)
#define FLASH_SR_PGERR (1u << 2)
#define FLASH_SR_WRPRTERR (1u << 4)
#define FLASH_SR_EOP (1u << 5)
#define FLASH_CR_PG (1u << 0)
#define FLASH_CR_PER (1u << 1)
#define FLASH_CR_STRT (1u << 6)
#define FLASH_CR_LOCK (1u << 7)

/* ---- GPIO (RM0008 §9.2) ---- */
struct gpio_regs {
    reg32 crl, crh, idr, odr, bsrr, brr, lckr;
};
#define GPIO(port) ((struct gpio_regs *)(uintptr_t)(0x40010800u + 0x400u * (uint32_t)(port)))
/* 4-bit pin configuration: CNF[1:0] MODE[1:0] */
#define GPIO_IN_ANALOG 0x0u
#define GPIO_IN_FLOATING 0x4u
#define GPIO_IN_PULL 0x8u      /* pull-up or -down as ODR says */
#define GPIO_OUT_PP_2MHZ 0x2u  /* general purpose push-pull */
#define GPIO_AF_PP_50MHZ 0xBu  /* alternate function push-pull */

/* ---- General-purpose timers TIM2..TIM4 (RM0008 §15.4) ---- */
struct tim_regs {
    reg32 cr1, cr2, smcr, dier, sr, egr, ccmr1, ccmr2, ccer, cnt, psc, arr, rcr;
    reg32 ccr1, ccr2, ccr3, ccr4, bdtr, dcr, dmar;
};
#define TIM2 ((struct tim_regs *)0x40000000u)
#define TIM3 ((struct tim_regs *)0x40000400u)
#define TIM_CR1_CEN (1u << 0)
#define TIM_CR1_ARPE (1u << 7)
#define TIM_CR2_MMS_OC4REF (7u << 4)  /* TRGO = OC4REF */
#define TIM_EGR_UG (1u << 0)
#define TIM_SMCR_SMS_ENCODER3 3u       /* count on TI1 and TI2 edges */
#define TIM_CCMR1_OC1_PWM1 (6u << 4)   /* OC1M = 110 */
#define TIM_CCMR1_OC1PE (1u << 3)
#define TIM_CCMR1_OC2_PWM1 (6u << 12)  /* OC2M = 110 */
#define TIM_CCMR1_OC2PE (1u << 11)
#define TIM_CCMR2_OC4_PWM2 (7u << 12)  /* OC4M = 111: active while CNT >= CCR4 */
#define TIM_CCMR2_OC4PE (1u << 11)
#define TIM_CCMR1_CC1S_TI1 (1u << 0)
#define TIM_CCMR1_CC2S_TI2 (1u << 8)
#define TIM_CCMR1_IC1F(f) ((uint32_t)(f) << 4)
#define TIM_CCMR1_IC2F(f) ((uint32_t)(f) << 12)
#define TIM_CCER_CC1E (1u << 0)
#define TIM_CCER_CC1P (1u << 1)
#define TIM_CCER_CC2E (1u << 4)

/* ---- ADC1 (RM0008 §11.12) ---- */
struct adc_regs {
    reg32 sr, cr1, cr2, smpr1, smpr2, jofr[4], htr, ltr, sqr1, sqr2, sqr3, jsqr, jdr[4], dr;
};
#define ADC1 ((struct adc_regs *)0x40012400u)
#define ADC_CR1_SCAN (1u << 8)
#define ADC_CR2_ADON (1u << 0)
#define ADC_CR2_CONT (1u << 1)
#define ADC_CR2_CAL (1u << 2)
#define ADC_CR2_RSTCAL (1u << 3)
#define ADC_CR2_DMA (1u << 8)
#define ADC_CR2_EXTSEL_TIM3_TRGO (4u << 17) /* regular group: table 69 */
#define ADC_CR2_EXTSEL_SWSTART (7u << 17)
#define ADC_CR2_EXTTRIG (1u << 20)
#define ADC_CR2_SWSTART (1u << 22)
#define ADC_SMP_13 2u /* 13.5 cycles: a low-impedance source (the shunt amplifier) */
#define ADC_SMP_41 4u /* 41.5 cycles: the dividers and the sensor (a few kOhm) */

/* ---- DMA1 (RM0008 §13.4); channel 1 serves ADC1 ---- */
struct dma_channel_regs {
    reg32 ccr, cndtr, cpar, cmar, reserved;
};
struct dma_regs {
    reg32 isr, ifcr;
    struct dma_channel_regs ch[7];
};
#define DMA1 ((struct dma_regs *)0x40020000u)
#define DMA_CCR_EN (1u << 0)
#define DMA_CCR_CIRC (1u << 5)
#define DMA_CCR_MINC (1u << 7)
#define DMA_CCR_PSIZE_16 (1u << 8)
#define DMA_CCR_MSIZE_16 (1u << 10)

/* ---- USART1 (RM0008 §27.6) ---- */
struct usart_regs {
    reg32 sr, dr, brr, cr1, cr2, cr3, gtpr;
};
#define USART1 ((struct usart_regs *)0x40013800u)
#define USART_SR_PE (1u << 0)
#define USART_SR_FE (1u << 1)
#define USART_SR_NE (1u << 2)
#define USART_SR_ORE (1u << 3)
#define USART_SR_RXNE (1u << 5)
#define USART_SR_TC (1u << 6)
#define USART_SR_TXE (1u << 7)
#define USART_CR1_RE (1u << 2)
#define USART_CR1_TE (1u << 3)
#define USART_CR1_RXNEIE (1u << 5)
#define USART_CR1_TCIE (1u << 6)
#define USART_CR1_TXEIE (1u << 7)
#define USART_CR1_UE (1u << 13)

/* ---- Independent watchdog (RM0008 §19.4) ---- */
struct iwdg_regs {
    reg32 kr, pr, rlr, sr;
};
#define IWDG ((struct iwdg_regs *)0x40003000u)
#define IWDG_KEY_RELOAD 0xAAAAu
#define IWDG_KEY_ACCESS 0x5555u
#define IWDG_KEY_START 0xCCCCu
#define IWDG_SR_PVU (1u << 0)
#define IWDG_SR_RVU (1u << 1)

#endif
