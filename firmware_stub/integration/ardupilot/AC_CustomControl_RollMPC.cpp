/**
 * @file AC_CustomControl_RollMPC.cpp
 * @brief ArduPilot glue of the generated roll MPC: centidegrees -> degrees in, degrees ->
 *        +/-4500 servo units out, fallback to the main controller on a bad solve.
 */
#include "AC_CustomControl_config.h"
#include "AC_CustomControl_RollMPC.h"

#if AP_CUSTOMCONTROL_ROLLMPC_ENABLED

#include <AP_Math/AP_Math.h>
#include <GCS_MAVLink/GCS.h>

static_assert(ROLLMPC_N_OUTPUTS == 1 && ROLLMPC_N_ACTUATORS == 2, "roll MPC with two aileron pairs");

const AP_Param::GroupInfo AC_CustomControl_RollMPC::var_info[] = {
    // @Param: THR_IN
    // @DisplayName: Inner aileron throw
    // @Description: Inner pair deflection at full servo travel (+/-4500); at least the controller's bound
    // @Units: deg
    // @Range: 1 45
    // @User: Advanced
    AP_GROUPINFO("THR_IN", 1, AC_CustomControl_RollMPC, _throw_inner_deg, 15.0f),

    // @Param: THR_OUT
    // @DisplayName: Outer aileron throw
    // @Description: Outer pair deflection at full servo travel (+/-4500)
    // @Units: deg
    // @Range: 1 45
    // @User: Advanced
    AP_GROUPINFO("THR_OUT", 2, AC_CustomControl_RollMPC, _throw_outer_deg, 15.0f),

    // @Param: OUT_FN
    // @DisplayName: Outer aileron servo function
    // @Description: SERVOn_FUNCTION value that carries the outer pair (the inner pair uses Aileron)
    // @User: Advanced
    AP_GROUPINFO("OUT_FN", 3, AC_CustomControl_RollMPC, _outer_function, int8_t(SRV_Channel::k_scripting1)),

    AP_GROUPEND
};

AC_CustomControl_RollMPC::AC_CustomControl_RollMPC(AC_CustomControl& frontend, AP_AHRS_View*& ahrs,
                                                   AC_AttitudeControl*& att_control,
                                                   AP_MotorsMulticopter*& motors, float dt) :
    AC_CustomControl_Backend(frontend, ahrs, att_control, motors, dt),
    _last_run_ms(0),
    _failsafe_events(0)
{
    AP_Param::setup_object_defaults(this, var_info);
    rollmpc_init(&_mpc);
}

Vector3f AC_CustomControl_RollMPC::update(void)
{
    const Vector3f main_output{_motors->get_roll(), _motors->get_pitch(), _motors->get_yaw()};

    // the generated controller is discretised at 10 ms: run it at 100 Hz whatever the
    // loop rate of the caller
    const uint32_t now_ms = AP_HAL::millis();
    if (now_ms - _last_run_ms < 10) {
        return main_output;
    }
    _last_run_ms = now_ms;

    // units: centidegrees and rad/s in, degrees and deg/s for the controller
    const rollmpc_real y[1] = {rollmpc_real(_ahrs->roll_sensor * 0.01f)};
    const rollmpc_real sched[1] = {rollmpc_real(degrees(_ahrs->get_gyro().x))};
    const float roll_cmd_deg = _att_control->get_att_target_euler_cd().x * 0.01f;
    for (uint16_t k = 0; k < ROLLMPC_HORIZON; k++) {
        _ref[k] = rollmpc_real(roll_cmd_deg);  // no preview: the command is held
    }

    const int status = rollmpc_step(&_mpc, y, sched, _ref, _u);
    if (status != ROLLMPC_OPTIMAL || !isfinite(_u[0]) || !isfinite(_u[1])) {
        // fallback: leave the ailerons to the main controller's output this sample
        _failsafe_events++;
        GCS_SEND_TEXT(MAV_SEVERITY_WARNING, "RollMPC: %s", rollmpc_status_message(status));
        return main_output;
    }

    // degrees -> +/-4500 servo units by the configured throw of each pair
    const float inner = constrain_float(float(_u[0]) / _throw_inner_deg * 4500.0f, -4500.0f, 4500.0f);
    const float outer = constrain_float(float(_u[1]) / _throw_outer_deg * 4500.0f, -4500.0f, 4500.0f);
    SRV_Channels::set_output_scaled(SRV_Channel::k_aileron, inner);
    SRV_Channels::set_output_scaled(SRV_Channel::Aux_servo_function_t(_outer_function.get()), outer);

    return main_output;
}

void AC_CustomControl_RollMPC::reset(void)
{
    rollmpc_init(&_mpc);
    _last_run_ms = 0;
}

#endif  // AP_CUSTOMCONTROL_ROLLMPC_ENABLED
