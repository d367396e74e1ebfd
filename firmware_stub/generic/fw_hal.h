/**
 * @file fw_hal.h
 * @brief The small HAL of the generic firmware main (fw_main.c): a timebase, the
 *        measurements, the setpoints and the actuator outputs of any generated design.
 *
 * Units are the design's own (its YAML's outputs, schedule and actuators); conversions
 * from sensor counts or to PWM live in the HAL. host/fw_hal_host.c reads samples from
 * stdin (tests, host runs), m4f/fw_hal_m4f.c ticks a Cortex-M4F's SysTick and exchanges
 * the values with board drivers through a mailbox.
 */
#ifndef FW_HAL_H
#define FW_HAL_H

#include <stdint.h>
#include "fw_design.h"

/** @brief Start the timebase at the design's sample period and the board's I/O. */
void fw_hal_init(uint32_t sample_period_us);

/** @brief Block until the next sample is due. @return 0 to stop the loop (host: end of input). */
int fw_hal_wait_sample(void);

/**
 * @brief This sample's inputs.
 * @param y        Out: measured outputs [FW_N_OUTPUTS]; NaN where a sensor gave nothing
 *                 new (the controller then runs its observers open loop).
 * @param sched    Out: scheduling signals [FW_N_SCHEDULE] (untouched without any).
 * @param setpoint Out: setpoint of every output [FW_N_OUTPUTS], held over the horizon.
 */
void fw_hal_read(fw_real *y, fw_real *sched, fw_real *setpoint);

/**
 * @brief Drive the actuators with this sample's command.
 * @param u      Command of every actuator [FW_N_ACTUATORS]: finite and within the
 *               design's bounds whatever the status.
 * @param status The step's status (<PREFIX>_OPTIMAL or another; the HAL may log it).
 * @param cycles Cycles of the solve (0 where the core has no cycle counter).
 */
void fw_hal_write(const fw_real *u, int status, uint32_t cycles);

#endif /* FW_HAL_H */
