/*
  Custom-controller backend of the roll MPC on Copter (see AC_CustomControl_RollMPC.h).
  Units and the glue live in AP_RollMPC; this file only wires Copter's sources to it.
 */
#include "AC_CustomControl_config.h"

#if AP_CUSTOMCONTROL_ROLLMPC_ENABLED

#include "AC_CustomControl_RollMPC.h"

#include <AC_AttitudeControl/AC_AttitudeControl.h>
#include <AP_Motors/AP_MotorsMulticopter.h>
#include <AP_Scheduler/AP_Scheduler.h>

const AP_Param::GroupInfo AC_CustomControl_RollMPC::var_info[] = {
    // @Group:
    // @Path: ../AP_RollMPC/AP_RollMPC.cpp
    AP_SUBGROUPINFO(_mpc, "", 1, AC_CustomControl_RollMPC, AP_RollMPC),

    AP_GROUPEND
};

AC_CustomControl_RollMPC::AC_CustomControl_RollMPC(AC_CustomControl& frontend, AP_AHRS_View*& ahrs,
                                                   AC_AttitudeControl*& att_control,
                                                   AP_MotorsMulticopter*& motors, float dt) :
    AC_CustomControl_Backend(frontend, ahrs, att_control, motors, dt)
{
    AP_Param::setup_object_defaults(this, var_info);
}

Vector3f AC_CustomControl_RollMPC::update(void)
{
    // the roll target of Copter's attitude controller (centidegrees); the MPC may fly while
    // the custom controller is switched on (RC option) and the motors are armed
    const float roll_target_cd = _att_control->get_att_target_euler_cd().x;
    _mpc.set_command(int32_t(roll_target_cd), _frontend.is_safe_to_run() && _motors->armed());
    // called at the loop rate: one sample on every ticks_per_sample-th scheduler tick
    if (rollglue_ap_sample_due(AP::scheduler().ticks32(), _mpc.ticks_per_sample())) {
        _mpc.update();
    }
    // run_custom_controller precedes motors_output_main, which computes the PWM
    _mpc.output();
    return Vector3f{_motors->get_roll(), _motors->get_pitch(), _motors->get_yaw()};
}

#endif  // AP_CUSTOMCONTROL_ROLLMPC_ENABLED
