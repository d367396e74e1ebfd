/**
 * @file rollctl_hal_m4f.c
 * @brief Cortex-M4F HAL of the firmware stub (generic STM32F4-class part).
 *
 * Timebase: SysTick at ROLLCTL_RATE_HZ from the core clock (ROLLCTL_CPU_HZ); cycle
 * counter: DWT CYCCNT. The IMU and the servo outputs are board specific: a sensor
 * driver (or its DMA interrupt) fills rollctl_m4f_io, and the servo pulse widths it
 * receives are to be copied into the PWM timer's compare registers of your board.
 */
#include "rollctl_hal.h"
#include "../integration/common/rollglue_cycles.h"

#ifndef ROLLCTL_CPU_HZ
#define ROLLCTL_CPU_HZ 168000000u
#endif

/* Cortex-M4 core registers (ARMv7-M architecture reference manual). */
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)

/** Sensor and servo mailbox shared with the board drivers (interrupt context). */
typedef struct {
    volatile float roll_deg;        /**< Written by the IMU driver, deg. */
    volatile float roll_rate_dps;   /**< Written by the IMU driver, deg/s. */
    volatile uint32_t imu_seq;      /**< Incremented by the IMU driver per new sample. */
    volatile float roll_cmd_deg;    /**< Written by the command source (RC, navigator). */
    volatile uint16_t servo_us[ROLLMPC_N_ACTUATORS]; /**< Pulse widths for the PWM timer. */
    volatile uint32_t overruns;     /**< Ticks that came before the sample finished. */
} rollctl_m4f_io_t;

rollctl_m4f_io_t rollctl_m4f_io;

static volatile uint32_t tick_pending;
static uint32_t imu_seq_seen;

/** @brief SysTick interrupt: marks the next 10 ms tick (vector in startup_m4f.c). */
void SysTick_Handler(void);

void SysTick_Handler(void)
{
    if (tick_pending != 0u) {
        ++rollctl_m4f_io.overruns;
    }
    tick_pending = 1u;
}

void rollctl_hal_init(void)
{
    rollglue_cycles_enable();
    /* 168 MHz / 100 Hz - 1 = 1,679,999 fits SysTick's 24-bit reload */
    SYST_RVR = ROLLCTL_CPU_HZ / ROLLCTL_RATE_HZ - 1u;
    SYST_CVR = 0u;
    SYST_CSR = 7u;      /* core clock, interrupt, enable */
    /* board: start the IMU driver and the PWM timer here */
}

int rollctl_hal_wait_tick(void)
{
    while (tick_pending == 0u) {
        __asm__ volatile ("wfi");
    }
    tick_pending = 0u;
    return 1;
}

int rollctl_hal_read_imu(rollmpc_real *roll_deg, rollmpc_real *roll_rate_dps)
{
    const uint32_t seq = rollctl_m4f_io.imu_seq;
    *roll_deg = (rollmpc_real)rollctl_m4f_io.roll_deg;
    *roll_rate_dps = (rollmpc_real)rollctl_m4f_io.roll_rate_dps;
    if (seq == imu_seq_seen) {
        return 0;  /* no new sample since the last tick: stale */
    }
    imu_seq_seen = seq;
    return 1;
}

rollmpc_real rollctl_hal_roll_command(void)
{
    return (rollmpc_real)rollctl_m4f_io.roll_cmd_deg;
}

int rollctl_hal_roll_preview(rollmpc_real *preview, int max_len)
{
    (void)preview;
    (void)max_len;
    return 0;  /* no preview source on this board: the command is held */
}

void rollctl_hal_write_servos(const rollmpc_real *deflection_deg, int n)
{
    int i;
    for (i = 0; i < n && i < ROLLMPC_N_ACTUATORS; ++i) {
        /* +/-ROLLCTL_SERVO_LIMIT_DEG -> 1000..2000 us around 1500 us */
        const rollmpc_real us = ROLLMPC_R(1500.0)
            + ROLLMPC_R(500.0) * deflection_deg[i] / ROLLCTL_SERVO_LIMIT_DEG;
        rollctl_m4f_io.servo_us[i] = (uint16_t)us;
    }
}

uint32_t rollctl_hal_cycles(void)
{
    return ROLLGLUE_CYCLES();
}

void rollctl_hal_telemetry(const rollctl *rc)
{
    (void)rc;  /* board: log rc->last_status, rc->failsafe_events, rc->max_cycles */
}
