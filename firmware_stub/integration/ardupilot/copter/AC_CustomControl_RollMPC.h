/*
  Custom-controller backend (type 3, CC3_*) that runs the generated roll MPC (AP_RollMPC)
  on Copter. It drives aileron servos of its own and never the motors: with
  replaces_motor_outputs() false the frontend calls update() every loop, active or not,
  and neither applies CC_AXIS_MASK nor touches the rate controllers' integrators. See
  firmware_stub/README.md of the rollmpc project.
 */
#pragma once

#include "AC_CustomControl_config.h"

#if AP_CUSTOMCONTROL_ROLLMPC_ENABLED

#include <AP_RollMPC/AP_RollMPC.h>

#include "AC_CustomControl_Backend.h"

class AC_CustomControl_RollMPC : public AC_CustomControl_Backend {
public:
    AC_CustomControl_RollMPC(AC_CustomControl& frontend, AP_AHRS_View*& ahrs,
                             AC_AttitudeControl*& att_control, AP_MotorsMulticopter*& motors,
                             float dt);

    // every loop: the attitude controller's roll target and the frontend's switch to the
    // MPC, a 100 Hz sample on every ticks_per_sample-th loop, the aileron servos; returns
    // the main controller's outputs (never applied to the motors)
    Vector3f update(void) override;

    // nothing to reset: the observers stay warm, the failure count restarts whenever the
    // switch drops, and a fresh engage starts its reference at the measured roll
    void reset(void) override {}

    bool replaces_motor_outputs() const override { return false; }

    static const struct AP_Param::GroupInfo var_info[];

private:
    // holds the controller instance (tens of KB): allocated once with this backend by
    // AC_CustomControl::init(), never on a stack
    AP_RollMPC _mpc;
};

#endif  // AP_CUSTOMCONTROL_ROLLMPC_ENABLED
