/**
 * @file AC_CustomControl_RollMPC.h
 * @brief ArduPilot custom-controller backend around the generated roll MPC (reference
 *        template; see firmware_stub/README.md).
 *
 * Units live here, not in the controller: ArduPilot gives the roll in centidegrees and
 * the gyro in rad/s; the controller works in degrees and deg/s; the aileron servos take
 * +/-4500 "angle" units (SRV_Channels::set_output_scaled). A non-finite output or a
 * non-optimal status leaves the ailerons to ArduPilot's own roll controller.
 */
#pragma once

#include "AC_CustomControl_Backend.h"

#ifndef AP_CUSTOMCONTROL_ROLLMPC_ENABLED
#define AP_CUSTOMCONTROL_ROLLMPC_ENABLED AP_CUSTOMCONTROL_ENABLED
#endif

#if AP_CUSTOMCONTROL_ROLLMPC_ENABLED

#include <SRV_Channel/SRV_Channel.h>

extern "C" {
#include "rollmpc.h"
}

class AC_CustomControl_RollMPC : public AC_CustomControl_Backend {
public:
    AC_CustomControl_RollMPC(AC_CustomControl& frontend, AP_AHRS_View*& ahrs,
                             AC_AttitudeControl*& att_control, AP_MotorsMulticopter*& motors,
                             float dt);

    // run one 100 Hz sample; returns the main controller's roll/pitch/yaw output (the
    // ailerons are driven through SRV_Channels, or left alone on a fallback)
    Vector3f update(void) override;

    // re-initialise the controller (observers, warm starts) on engage
    void reset(void) override;

    static const struct AP_Param::GroupInfo var_info[];

protected:
    AP_Float _throw_inner_deg;   // inner pair deflection at +/-4500
    AP_Float _throw_outer_deg;   // outer pair deflection at +/-4500
    AP_Int8 _outer_function;     // SRV function of the outer pair (default Scripting1)

private:
    // one controller instance: ~32 KB for N = 100 in float, held in the backend object
    // (allocated once at boot by AC_CustomControl::init()), never on the stack
    rollmpc_ctrl _mpc;
    rollmpc_real _ref[ROLLMPC_HORIZON * ROLLMPC_N_OUTPUTS];
    rollmpc_real _u[ROLLMPC_N_ACTUATORS];
    uint32_t _last_run_ms;
    uint32_t _failsafe_events;
};

#endif  // AP_CUSTOMCONTROL_ROLLMPC_ENABLED
