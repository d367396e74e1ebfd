/**
 * @file fw_main.c
 * @brief Minimal bare-metal main for any generated design: one <prefix>_step() per
 *        sample period through the HAL of fw_hal.h.
 *
 * The reference is each output's setpoint held over the horizon. The controller's
 * command is always finite and within the bounds (on a non-finite input it holds the last
 * one), so it goes to the actuators as it is; what to do beyond that on a status other
 * than <PREFIX>_OPTIMAL (count it, hand over to a backup) is the application's policy,
 * which the HAL sees through the status.
 */
#include "fw_hal.h"

/* Static: the instance holds the solver's work arrays, never on the stack. */
static FW_FN(_ctrl) fw_ctrl;
static fw_real fw_ref[FW_HORIZON * FW_N_OUTPUTS];

/** @brief r(k+1..k+N), output-major per step: the setpoints held. */
static void hold_setpoints(const fw_real *setpoint)
{
    int k, i;
    for (k = 0; k < FW_HORIZON; ++k) {
        for (i = 0; i < FW_N_OUTPUTS; ++i) {
            fw_ref[k * FW_N_OUTPUTS + i] = setpoint[i];
        }
    }
}

/**
 * @brief Start the HAL and the controller, then run one step per sample period.
 * @return 0 when the HAL stops the loop (host only).
 */
int main(void)
{
    fw_real y[FW_N_OUTPUTS], sched[FW_SCHEDULE_LEN], setpoint[FW_N_OUTPUTS], u[FW_N_ACTUATORS];
    int i;
    for (i = 0; i < FW_SCHEDULE_LEN; ++i) {
        sched[i] = (fw_real)0;
    }
    fw_hal_init(FW_SAMPLE_PERIOD_US);
    FW_FN(_init)(&fw_ctrl);
    while (fw_hal_wait_sample()) {
        int status;
        fw_hal_read(y, sched, setpoint);
        hold_setpoints(setpoint);
        status = FW_FN(_step)(&fw_ctrl, y, FW_N_SCHEDULE > 0 ? sched : (const fw_real *)0,
                              fw_ref, u);
        fw_hal_write(u, status, FW_FN(_last_info)(&fw_ctrl)->solve_ticks);
    }
    return 0;
}
