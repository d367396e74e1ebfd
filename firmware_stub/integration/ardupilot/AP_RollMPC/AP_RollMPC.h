/*
  AP_RollMPC: the generated roll MPC (rollmpc) for ArduPilot, over the portable glue core
  (rollglue.h) and its ArduPilot units (rollglue_ap.h). Hand-written; see
  firmware_stub/README.md and docs/integration.md of the rollmpc project.

  Three calls from the vehicle, all on the main thread:
  - set_command(): every loop in which the vehicle's own roll controller runs (ArduPlane:
    stabilize_roll()), with its roll command and whether the MPC may fly now;
  - update(): one controller sample, 100 Hz (ArduPlane: a scheduler task; Copter: the
    custom controller's loop-rate call decimated by the scheduler's ticks);
  - output(): every loop just before SRV_Channels::calc_pwm().
  The solve runs in a worker thread below the main loop and the sensor buses (its worst
  case, several ms on an F4, must never stretch a main-loop tick). The MPC's values reach
  the aileron servos only while they are valid and at most two samples old and the vehicle
  allowed it in this very loop; otherwise the vehicle's own output flies, at once.
  Nothing here ever writes a parameter.
 */
#pragma once

#include <AP_HAL/AP_HAL_Boards.h>

#ifndef AP_ROLLMPC_ENABLED
#define AP_ROLLMPC_ENABLED 1
#endif

#if AP_ROLLMPC_ENABLED

#include <AP_HAL/AP_HAL.h>
#include <AP_HAL/Semaphores.h>
#include <AP_Param/AP_Param.h>
#include "rollglue_ap.h"

class AP_RollMPC {
public:
    AP_RollMPC();

    CLASS_NO_COPY(AP_RollMPC);

    static const struct AP_Param::GroupInfo var_info[];

    // the vehicle's roll command (centidegrees) in this loop; may_fly: the vehicle lets the
    // MPC drive the ailerons in this loop (mode, armed and flying, not inverted, ...)
    void set_command(int32_t roll_cmd_cd, bool may_fly);

    // one controller sample: hands the inputs to the worker, never waits for a solve;
    // starts the worker on the first call with RMPC_ENABLE set
    void update();

    // just before SRV_Channels::calc_pwm(): the MPC's aileron values, or the vehicle's own
    void output();

    // main-loop ticks per sample; 0 when SCHED_LOOP_RATE is not a multiple of 100 Hz
    uint16_t ticks_per_sample() const;

private:
    // parameters (ranges enforced by rollglue_set_params, never by AP_Param)
    AP_Int8 _enable;
    AP_Int16 _timeout_ms;
    AP_Int16 _frozen;
    AP_Int16 _warmup;
    AP_Int16 _max_fail;
    AP_Float _slew_dps;
    AP_Float _throw_in_deg;
    AP_Float _throw_out_deg;
    AP_Int8 _in_l, _in_r, _out_l, _out_r;
    AP_Int8 _reversed;

    enum class Start : uint8_t { NOT_YET, RUNNING, REFUSED };

    void start();
    void worker();
    void post_params();
    void sample_inputs(rollglue_ap_sample &s) const;
    void report();
    void log_sample(const rollglue_output &out, float own, uint32_t driven);

    // the worker's alone once it runs: the controller instance (tens of KB), allocated
    // with this object, never on a stack
    rollglue _glue;

    // shared with the worker, under _sem
    HAL_Semaphore _sem;
    HAL_BinarySemaphore _wake;
    struct {
        rollglue_ap_sample sample;
        uint64_t sample_us;            // when update() took it
        rollglue_params params;
        bool new_params;
        rollglue_output out;
        uint64_t out_sample_us;        // when the sample behind out was taken
        rollglue_telemetry tm;
        int params_result;
        uint32_t solve_us, max_solve_us;
    } _shared;

    // main thread only
    Start _start = Start::NOT_YET;
    int32_t _cmd_cd = 0;
    uint64_t _cmd_us = 0;
    bool _may_fly = false;            // as of the latest set_command()
    bool _may_fly_this_loop = false;  // set_command() ran in this loop and allowed it
    float _applied_scaled[ROLLGLUE_MAX_CHANNELS];
    uint32_t _owned_mask = 0;         // channels the MPC drove in the latest loop
    uint64_t _logged_sample_us = 0;   // the worker output last written to the log
    uint32_t _samples = 0;
    rollglue_params _last_params;
    int _foreign_channel = -1;
    struct {
        int params_result;
        int foreign_channel;
        uint32_t failures, engagements;
        int state;
        uint32_t last_ms;
    } _reported;
};

#endif  // AP_ROLLMPC_ENABLED
