/**
 * @file rollglue_cycles.h
 * @brief CPU cycle counter for the generated controller's P_TIMESTAMP(): the DWT cycle
 *        counter (CYCCNT) on Cortex-M3/M4/M7/M33, 0 elsewhere (host, SITL).
 *
 * Force-include it when compiling the generated sources and define the prefix's
 * timestamp macro from it, e.g. for the prefix rollmpc:
 *     -include rollglue_cycles.h '-DROLLMPC_TIMESTAMP()=ROLLGLUE_CYCLES()'
 * rollmpc_last_info()->solve_ticks then holds the cycles of the last QP solve.
 * rollglue_cycles_enable() switches the counter on (privileged code: bare metal, NuttX
 * flat builds); it is harmless when a debugger or the RTOS already did.
 */
#ifndef ROLLGLUE_CYCLES_H
#define ROLLGLUE_CYCLES_H

#include <stdint.h>

#if defined(__ARM_ARCH_7M__) || defined(__ARM_ARCH_7EM__) || defined(__ARM_ARCH_8M_MAIN__)
/* ARMv7-M / ARMv8-M architecture reference manuals: DEMCR, DWT_CTRL, DWT_CYCCNT */
#define ROLLGLUE_DEMCR (*(volatile uint32_t *)0xE000EDFCu)
#define ROLLGLUE_DWT_CTRL (*(volatile uint32_t *)0xE0001000u)
#define ROLLGLUE_DWT_CYCCNT (*(volatile uint32_t *)0xE0001004u)
#define ROLLGLUE_HAS_CYCLES 1
#define ROLLGLUE_CYCLES() (ROLLGLUE_DWT_CYCCNT)

/** @brief Enable the DWT cycle counter (TRCENA, then CYCCNTENA); keeps its count. */
static inline void rollglue_cycles_enable(void)
{
    ROLLGLUE_DEMCR |= 1u << 24;
    ROLLGLUE_DWT_CTRL |= 1u;
}
#else
#define ROLLGLUE_HAS_CYCLES 0
#define ROLLGLUE_CYCLES() (0u)

/** @brief No cycle counter on this architecture: nothing to enable. */
static inline void rollglue_cycles_enable(void)
{
}
#endif

#endif /* ROLLGLUE_CYCLES_H */
