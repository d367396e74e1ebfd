/**
 * @file fw_hal_host.c
 * @brief Host HAL of the generic firmware: one sample per line on stdin, one line out.
 *
 * In:  y[FW_N_OUTPUTS] sched[FW_N_SCHEDULE] setpoint[FW_N_OUTPUTS], whitespace separated
 *      ("nan" for a missing measurement); the loop stops at the end of input or at a line
 *      with too few numbers.
 * Out: status u[FW_N_ACTUATORS] (%.17g: a double tree's command prints exactly).
 */
#include <stdio.h>
#include <stdlib.h>
#include "../fw_hal.h"

#define FW_LINE_MAX 4096
#define FW_N_IN (2 * FW_N_OUTPUTS + FW_N_SCHEDULE)

static double fw_in[FW_N_IN];
static char fw_line[FW_LINE_MAX]; /* static: ArduPilot's frame limit applies here too */

void fw_hal_init(uint32_t sample_period_us)
{
    (void)sample_period_us; /* the host runs as fast as its input comes */
}

int fw_hal_wait_sample(void)
{
    char *p = fw_line, *end;
    int i;
    if (fgets(fw_line, sizeof fw_line, stdin) == NULL) {
        return 0;
    }
    for (i = 0; i < FW_N_IN; ++i, p = end) {
        fw_in[i] = strtod(p, &end);
        if (end == p) {
            return 0;
        }
    }
    return 1;
}

void fw_hal_read(fw_real *y, fw_real *sched, fw_real *setpoint)
{
    int i;
    for (i = 0; i < FW_N_OUTPUTS; ++i) {
        y[i] = (fw_real)fw_in[i];
        setpoint[i] = (fw_real)fw_in[FW_N_OUTPUTS + FW_N_SCHEDULE + i];
    }
    for (i = 0; i < FW_N_SCHEDULE; ++i) {
        sched[i] = (fw_real)fw_in[FW_N_OUTPUTS + i];
    }
}

void fw_hal_write(const fw_real *u, int status, uint32_t cycles)
{
    int i;
    (void)cycles;
    printf("%d", status);
    for (i = 0; i < FW_N_ACTUATORS; ++i) {
        printf(" %.17g", (double)u[i]);
    }
    printf("\n");
    fflush(stdout);
}
