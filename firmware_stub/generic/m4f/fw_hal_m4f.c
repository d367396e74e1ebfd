/**
 * @file fw_hal_m4f.c
 * @brief Cortex-M4F HAL of the generic firmware (generic STM32F4-class part).
 *
 * Timebase: SysTick at 1 kHz from the core clock (FW_CPU_HZ), a sample every
 * round(period / 1 ms) ticks, so any sample period from 1 ms to hours fits SysTick's
 * 24-bit reload. The measurements and the actuator outputs are board specific: sensor
 * drivers fill fw_m4f_io (and count io_seq up per new sample), and the commands it
 * receives are to be copied into the board's PWM or DAC registers.
 */
#include <math.h>
#include "../fw_hal.h"
#include "../../integration/common/rollglue_cycles.h"

#ifndef FW_CPU_HZ
#define FW_CPU_HZ 168000000u
#endif
#define FW_TICK_HZ 1000u

/* Cortex-M4 core registers (ARMv7-M architecture reference manual). */
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)

/** Mailbox shared with the board drivers (interrupt context). */
typedef struct {
    volatile fw_real y[FW_N_OUTPUTS];          /**< Measured outputs (drivers). */
    volatile fw_real sched[FW_SCHEDULE_LEN];   /**< Scheduling signals (drivers). */
    volatile fw_real setpoint[FW_N_OUTPUTS];   /**< Setpoints (command source). */
    volatile uint32_t io_seq;                  /**< Drivers: +1 per new measurement. */
    volatile fw_real u[FW_N_ACTUATORS];        /**< Commands for the actuators. */
    volatile int status;                       /**< Status of the last step. */
    volatile uint32_t cycles;                  /**< Cycles of the last solve. */
    volatile uint32_t overruns;                /**< Samples due before the last finished. */
} fw_m4f_io_t;

fw_m4f_io_t fw_m4f_io;

static volatile uint32_t fw_samples_due;
static uint32_t fw_ticks_per_sample = 1u, fw_tick_count, fw_seq_seen;

/** @brief SysTick interrupt (vector in m4f/startup_m4f.c): one 1 ms tick. */
void SysTick_Handler(void);

void SysTick_Handler(void)
{
    if (++fw_tick_count < fw_ticks_per_sample) {
        return;
    }
    fw_tick_count = 0u;
    if (fw_samples_due != 0u) {
        ++fw_m4f_io.overruns;
    }
    fw_samples_due = 1u;
}

void fw_hal_init(uint32_t sample_period_us)
{
    const uint32_t ticks = (sample_period_us + 500u) / 1000u;
    fw_ticks_per_sample = ticks > 0u ? ticks : 1u;
    rollglue_cycles_enable();
    SYST_RVR = FW_CPU_HZ / FW_TICK_HZ - 1u;
    SYST_CVR = 0u;
    SYST_CSR = 7u; /* core clock, interrupt, enable */
    /* board: start the sensor drivers and the actuator timers here */
}

int fw_hal_wait_sample(void)
{
    while (fw_samples_due == 0u) {
        __asm__ volatile ("wfi");
    }
    fw_samples_due = 0u;
    return 1;
}

void fw_hal_read(fw_real *y, fw_real *sched, fw_real *setpoint)
{
    int i;
    const uint32_t seq = fw_m4f_io.io_seq;
    for (i = 0; i < FW_N_OUTPUTS; ++i) {
        /* nothing new since the last sample: NaN, the observers run open loop */
        y[i] = seq == fw_seq_seen ? (fw_real)NAN : fw_m4f_io.y[i];
        setpoint[i] = fw_m4f_io.setpoint[i];
    }
    for (i = 0; i < FW_N_SCHEDULE; ++i) {
        sched[i] = fw_m4f_io.sched[i];
    }
    fw_seq_seen = seq;
}

void fw_hal_write(const fw_real *u, int status, uint32_t cycles)
{
    int i;
    for (i = 0; i < FW_N_ACTUATORS; ++i) {
        fw_m4f_io.u[i] = u[i];
    }
    fw_m4f_io.status = status;
    fw_m4f_io.cycles = cycles;
}
