/**
 * @file rollctl_hal_host.c
 * @brief Host HAL of the firmware stub: one sample per line on stdin, one line out.
 *
 * In:  "roll_deg roll_rate_dps roll_cmd_deg imu_valid [preview_1 ... preview_n]"
 *      (numbers as strtod() reads them, hex floats included, so a test can pass exact
 *      values; imu_valid 0 marks a missing IMU sample).
 * Out: "u_inner u_outer status failsafe_events mode" after every sample, u as hex floats
 *      (%a, exact), flushed, so a test can drive the loop through a pipe.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "rollctl_hal.h"

#define LINE_MAX_CHARS (64 * (ROLLMPC_HORIZON + 8))

static char line_buf[LINE_MAX_CHARS];
static double imu_roll, imu_rate, roll_cmd;
static int imu_ok;
static double preview_buf[ROLLMPC_HORIZON];
static int preview_n;

void rollctl_hal_init(void)
{
    imu_roll = imu_rate = roll_cmd = 0.0;
    imu_ok = 0;
    preview_n = 0;
}

int rollctl_hal_wait_tick(void)
{
    double v[4];
    char *p = line_buf, *end;
    int i;
    if (fgets(line_buf, (int)sizeof line_buf, stdin) == 0) {
        return 0;
    }
    for (i = 0; i < 4; ++i) {
        v[i] = strtod(p, &end);
        if (end == p) {
            fprintf(stderr, "rollctl_host: bad input line\n");
            return 0;
        }
        p = end;
    }
    imu_roll = v[0];
    imu_rate = v[1];
    roll_cmd = v[2];
    imu_ok = fabs(v[3]) >= 1; /* (int)v[3] != 0 without the cast: NaN is UB there, invalid here */
    for (preview_n = 0; preview_n < ROLLMPC_HORIZON; ++preview_n) {
        const double x = strtod(p, &end);
        if (end == p) {
            break;
        }
        preview_buf[preview_n] = x;
        p = end;
    }
    return 1;
}

int rollctl_hal_read_imu(rollmpc_real *roll_deg, rollmpc_real *roll_rate_dps)
{
    *roll_deg = (rollmpc_real)imu_roll;
    *roll_rate_dps = (rollmpc_real)imu_rate;
    return imu_ok;
}

rollmpc_real rollctl_hal_roll_command(void)
{
    return (rollmpc_real)roll_cmd;
}

int rollctl_hal_roll_preview(rollmpc_real *preview, int max_len)
{
    int i;
    const int n = preview_n < max_len ? preview_n : max_len;
    for (i = 0; i < n; ++i) {
        preview[i] = (rollmpc_real)preview_buf[i];
    }
    return n;
}

void rollctl_hal_write_servos(const rollmpc_real *deflection_deg, int n)
{
    (void)deflection_deg; /* reported with the telemetry line */
    (void)n;
}

uint32_t rollctl_hal_cycles(void)
{
    return 0u; /* no cycle counter on the host: see rollmpc report for target cycles */
}

void rollctl_hal_telemetry(const rollctl *rc)
{
    int i;
    for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
        printf("%a ", (double)rc->u[i]);
    }
    printf("%d %lu %d\n", rc->last_status, (unsigned long)rc->failsafe_events,
        rollmpc_last_info(&rc->mpc)->mode);
    fflush(stdout);
}
