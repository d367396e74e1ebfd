/**
 * @file startup_m4f.c
 * @brief Startup code and vector table of a generic STM32F4-class Cortex-M4F part.
 *
 * Reset: copy .data from flash, zero .bss, enable the FPU (CPACR: full access to CP10
 * and CP11) before any floating-point instruction runs, then main(). The external
 * interrupts all go to Default_Handler; only SysTick is used.
 */
#include <stdint.h>

/* Symbols of cortex_m_generic.ld. */
extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;

int main(void);
void Reset_Handler(void);
void Default_Handler(void);
void NMI_Handler(void) __attribute__((weak, alias("Default_Handler")));
void HardFault_Handler(void) __attribute__((weak, alias("Default_Handler")));
void MemManage_Handler(void) __attribute__((weak, alias("Default_Handler")));
void BusFault_Handler(void) __attribute__((weak, alias("Default_Handler")));
void UsageFault_Handler(void) __attribute__((weak, alias("Default_Handler")));
void SVC_Handler(void) __attribute__((weak, alias("Default_Handler")));
void DebugMon_Handler(void) __attribute__((weak, alias("Default_Handler")));
void PendSV_Handler(void) __attribute__((weak, alias("Default_Handler")));
void SysTick_Handler(void) __attribute__((weak, alias("Default_Handler")));

#define SCB_CPACR (*(volatile uint32_t *)0xE000ED88u)
#define N_EXTERNAL_IRQ 82  /* STM32F405/407 */

typedef void (*rollctl_vector)(void);

/** The vector table: initial stack pointer, then the handlers (ARMv7-M layout). */
typedef struct {
    uint32_t *initial_sp;
    rollctl_vector core[15];
    rollctl_vector external[N_EXTERNAL_IRQ];
} rollctl_vector_table;

#define D Default_Handler
__attribute__((section(".isr_vector"), used))
const rollctl_vector_table rollctl_vectors = {
    &_estack,
    {
        Reset_Handler, NMI_Handler, HardFault_Handler, MemManage_Handler,
        BusFault_Handler, UsageFault_Handler, 0, 0, 0, 0, SVC_Handler, DebugMon_Handler,
        0, PendSV_Handler, SysTick_Handler
    },
    {
        D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D,
        D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D,
        D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D,
        D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D, D,
        D, D
    }
};
#undef D

void Reset_Handler(void)
{
    uint32_t *src = &_sidata;
    uint32_t *dst = &_sdata;
    while (dst < &_edata) {
        *dst++ = *src++;
    }
    for (dst = &_sbss; dst < &_ebss; ++dst) {
        *dst = 0u;
    }
    SCB_CPACR |= 0xFu << 20;  /* CP10, CP11: full access (the FPU) */
    __asm__ volatile ("dsb\n\tisb" ::: "memory");
    (void)main();
    for (;;) {
    }
}

void Default_Handler(void)
{
    for (;;) {
    }
}
