/**
 * @file fw_design.h
 * @brief The generated controller the generic firmware runs, chosen at compile time.
 *
 * Any tree of `rollmpc generate` serves: its prefix comes in as FW_PREFIX (e.g. drives),
 * FW_PREFIX_UPPER (DRIVES) and FW_HEADER ("drives.h"); rollmpc_fw.mk and rollmpc_fw.cmake
 * read them from the tree's <prefix>_config.h. Sizes and the sample period are the
 * tree's own macros, never restated here.
 */
#ifndef FW_DESIGN_H
#define FW_DESIGN_H

#ifndef FW_PREFIX
#define FW_PREFIX rollmpc
#define FW_PREFIX_UPPER ROLLMPC
#define FW_HEADER "rollmpc.h"
#endif

#define FW_PASTE_(a, b) a##b
#define FW_PASTE(a, b) FW_PASTE_(a, b)
/** A function or type of the controller: FW_FN(_step) = <prefix>_step. */
#define FW_FN(name) FW_PASTE(FW_PREFIX, name)
/** A macro of the controller: FW_K(_HORIZON) = <PREFIX>_HORIZON. */
#define FW_K(name) FW_PASTE(FW_PREFIX_UPPER, name)

#include FW_HEADER

typedef FW_FN(_real) fw_real;

#define FW_N_OUTPUTS FW_K(_N_OUTPUTS)
#define FW_N_SCHEDULE FW_K(_N_SCHEDULE)
#define FW_N_ACTUATORS FW_K(_N_ACTUATORS)
#define FW_HORIZON FW_K(_HORIZON)
/** The sample period of the design, us: the main loop runs one step per period. */
#define FW_SAMPLE_PERIOD_US FW_K(_SAMPLE_PERIOD_US)
/** Arrays of the schedule need one element even for a design without one. */
#define FW_SCHEDULE_LEN (FW_N_SCHEDULE > 0 ? FW_N_SCHEDULE : 1)

#endif /* FW_DESIGN_H */
