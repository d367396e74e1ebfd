/*
  AP_RollMPC: see AP_RollMPC.h. Units: AHRS roll and the roll command in centidegrees, the
  gyro in rad/s, aileron servos in +/-4500 scaled units; the conversions to the glue's
  degrees and normalised values are rollglue_ap.c's, the controller never sees ArduPilot's.
 */
#include "AP_RollMPC.h"

#if AP_ROLLMPC_ENABLED

#include <string.h>
#include <AP_AHRS/AP_AHRS.h>
#include <AP_InertialSensor/AP_InertialSensor.h>
#include <AP_Logger/AP_Logger.h>
#include <AP_Scheduler/AP_Scheduler.h>
#include <GCS_MAVLink/GCS.h>
#include <SRV_Channel/SRV_Channel.h>

extern const AP_HAL::HAL& hal;

static_assert(ROLLGLUE_N_ACT == 1 || ROLLGLUE_N_ACT == 2,
              "one or two aileron pairs: inner (RMPC_IN_*), outer (RMPC_OUT_*)");
static_assert(NUM_SERVO_CHANNELS <= ROLLGLUE_MAX_CHANNELS, "the glue must address every servo output");

namespace {
constexpr uint32_t kSamplePeriodUs = 1000000U / ROLLGLUE_SAMPLE_HZ;
// older values are never put on a servo: the vehicle's own output flies instead
constexpr uint64_t kMaxOutputAgeUs = 2 * kSamplePeriodUs;
constexpr uint32_t kMessageIntervalMs = 2000;  // at most one text per 2 s
// rollmpc_step's deepest path is ~0.5 KB (rollmpc report: stack_bytes), the worker's own
// frame ~0.6 KB; the controller instance lives in this object, not on the stack
constexpr uint32_t kWorkerStackBytes = 3072;
constexpr uint32_t kWakeTimeoutUs = 100000;

// the parameters behind each rollglue_params_result, for the ground station
const char *const kParamNames[] = {
    "", "TIMEOUT", "FROZEN", "WARMUP", "MAX_FAIL", "SLEW", "IN_L/IN_R/OUT_L/OUT_R",
    "IN_L/IN_R/OUT_L/OUT_R (one servo twice)", "REV", "THROW_IN/THROW_OUT", "(servo count)",
};
}

const AP_Param::GroupInfo AP_RollMPC::var_info[] = {
    // @Param: ENABLE
    // @DisplayName: Roll MPC enable
    // @Description: Lets the roll MPC fly the ailerons whenever the vehicle allows it (ArduPlane: FBWA and the auto-throttle modes, armed and flying, not inverted). Never written by the MPC itself: a lock-out after RMPC_MAX_FAIL failures clears when the vehicle withdraws the request (another mode, or this parameter 0).
    // @Values: 0:Disabled,1:Enabled
    // @User: Advanced
    AP_GROUPINFO_FLAGS("ENABLE", 1, AP_RollMPC, _enable, 0, AP_PARAM_FLAG_ENABLE),

    // @Param: TIMEOUT
    // @DisplayName: Input timeout
    // @Description: Oldest AHRS attitude and roll command the MPC flies on; an older one hands the ailerons back at once.
    // @Units: ms
    // @Range: 5 100
    // @User: Advanced
    AP_GROUPINFO("TIMEOUT", 2, AP_RollMPC, _timeout_ms, 25),

    // @Param: FROZEN
    // @DisplayName: Frozen attitude samples
    // @Description: Samples in a row with a bit-identical roll and roll rate that mark the attitude as frozen (hand-back); 0 disables the check.
    // @Range: 0 1000
    // @User: Advanced
    AP_GROUPINFO("FROZEN", 3, AP_RollMPC, _frozen, 25),

    // @Param: WARMUP
    // @DisplayName: Observer warm-up samples
    // @Description: Samples the observers must follow the aircraft on the vehicle's own aileron command before an engage.
    // @Range: 1 1000
    // @User: Advanced
    AP_GROUPINFO("WARMUP", 4, AP_RollMPC, _warmup, 50),

    // @Param: MAX_FAIL
    // @DisplayName: Failures before lock-out
    // @Description: Failed samples in a row (bad input, failed solve) after which the MPC stays out until the vehicle withdraws the request.
    // @Range: 1 1000
    // @User: Advanced
    AP_GROUPINFO("MAX_FAIL", 5, AP_RollMPC, _max_fail, 10),

    // @Param: SLEW
    // @DisplayName: Reference ramp rate
    // @Description: At an engage the reference starts at the measured roll and ramps to the command at this rate; 0 steps.
    // @Units: deg/s
    // @Range: 0 360
    // @User: Advanced
    AP_GROUPINFO("SLEW", 6, AP_RollMPC, _slew_dps, 30.0f),

    // @Param: THROW_IN
    // @DisplayName: Inner aileron throw
    // @Description: Inner pair deflection at a scaled output of 4500 (full servo travel).
    // @Units: deg
    // @Range: 1 90
    // @User: Advanced
    AP_GROUPINFO("THROW_IN", 7, AP_RollMPC, _throw_in_deg, 15.0f),

    // @Param: THROW_OUT
    // @DisplayName: Outer aileron throw
    // @Description: Outer pair deflection at a scaled output of 4500 (full servo travel).
    // @Units: deg
    // @Range: 1 90
    // @User: Advanced
    AP_GROUPINFO("THROW_OUT", 8, AP_RollMPC, _throw_out_deg, 15.0f),

    // @Param: IN_L
    // @DisplayName: Inner pair, left servo
    // @Description: SERVOn output of the inner pair's left servo (SERVOn_FUNCTION must be 4, Aileron); 0 = not configured, the MPC stays off.
    // @Range: 0 32
    // @User: Advanced
    AP_GROUPINFO("IN_L", 9, AP_RollMPC, _in_l, 0),

    // @Param: IN_R
    // @DisplayName: Inner pair, right servo
    // @Description: SERVOn output of the inner pair's right servo (Aileron); 0 = none (one servo or a Y-cable drives the pair).
    // @Range: 0 32
    // @User: Advanced
    AP_GROUPINFO("IN_R", 10, AP_RollMPC, _in_r, 0),

    // @Param: OUT_L
    // @DisplayName: Outer pair, left servo
    // @Description: SERVOn output of the outer pair's left servo (Aileron); 0 = not configured, the MPC stays off.
    // @Range: 0 32
    // @User: Advanced
    AP_GROUPINFO("OUT_L", 11, AP_RollMPC, _out_l, 0),

    // @Param: OUT_R
    // @DisplayName: Outer pair, right servo
    // @Description: SERVOn output of the outer pair's right servo (Aileron); 0 = none.
    // @Range: 0 32
    // @User: Advanced
    AP_GROUPINFO("OUT_R", 12, AP_RollMPC, _out_r, 0),

    // @Param: REV
    // @DisplayName: Reversed MPC servos
    // @Description: Servos whose MPC value is reversed on top of SERVOn_REVERSED. With the ailerons set up for ArduPlane (a positive aileron output rolls right on every servo) none is.
    // @Bitmask: 0:Inner left,1:Inner right,2:Outer left,3:Outer right
    // @User: Advanced
    AP_GROUPINFO("REV", 13, AP_RollMPC, _reversed, 0),

    AP_GROUPEND
};

AP_RollMPC::AP_RollMPC()
{
    AP_Param::setup_object_defaults(this, var_info);
    memset(&_shared, 0, sizeof(_shared));
    memset(&_last_params, 0, sizeof(_last_params));
    memset(&_reported, 0, sizeof(_reported));
    _reported.foreign_channel = -1;
    for (float &v : _applied_scaled) {
        v = NAN;
    }
}

uint16_t AP_RollMPC::ticks_per_sample() const
{
    return rollglue_ap_ticks_per_sample(AP::scheduler().get_loop_rate_hz());
}

void AP_RollMPC::set_command(int32_t roll_cmd_cd, bool may_fly)
{
    _cmd_cd = roll_cmd_cd;
    _cmd_us = AP_HAL::micros64();
    _may_fly = may_fly && _enable > 0;
    _may_fly_this_loop = _may_fly;
}

void AP_RollMPC::start()
{
    const uint16_t loop_rate_hz = AP::scheduler().get_loop_rate_hz();
    if (rollglue_ap_ticks_per_sample(loop_rate_hz) == 0) {
        GCS_SEND_TEXT(MAV_SEVERITY_ERROR, "RollMPC off: SCHED_LOOP_RATE %u is not a multiple of %u",
                      unsigned(loop_rate_hz), unsigned(ROLLGLUE_SAMPLE_HZ));
        _start = Start::REFUSED;
        return;
    }
    rollglue_init(&_glue);
    post_params();
    // below the main loop and every sensor bus, above logging, storage and the UARTs
    if (!hal.scheduler->thread_create(FUNCTOR_BIND_MEMBER(&AP_RollMPC::worker, void), "RollMPC",
                                      kWorkerStackBytes, AP_HAL::Scheduler::PRIORITY_I2C, -1)) {
        GCS_SEND_TEXT(MAV_SEVERITY_ERROR, "RollMPC off: no worker thread");
        _start = Start::REFUSED;
        return;
    }
    _start = Start::RUNNING;
}

// RMPC_* -> glue parameters for the worker, when they changed; the glue checks the ranges,
// this the servo functions (a refused set keeps the previous one)
void AP_RollMPC::post_params()
{
    rollglue_ap_settings s {};
    s.timeout_ms = _timeout_ms;
    s.frozen_samples = _frozen;
    s.warmup_samples = _warmup;
    s.max_failures = _max_fail;
    s.slew_dps = _slew_dps;
    // a one-actuator controller (e.g. c172_roll) uses the inner pair's parameters only
    const float throw_deg[2] {_throw_in_deg, _throw_out_deg};
    const int32_t servo[2][2] {{_in_l, _in_r}, {_out_l, _out_r}};
    for (uint8_t a = 0; a < ROLLGLUE_N_ACT; a++) {
        s.throw_deg[a] = throw_deg[a];
        s.servo[a][0] = servo[a][0];
        s.servo[a][1] = servo[a][1];
    }
    s.reversed = _reversed;
    rollglue_params p {};
    rollglue_ap_params(&s, &p);

    uint16_t functions[NUM_SERVO_CHANNELS];
    for (uint8_t c = 0; c < NUM_SERVO_CHANNELS; c++) {
        functions[c] = uint16_t(SRV_Channels::channel_function(c));
    }
    _foreign_channel = rollglue_ap_foreign_channel(&p, functions, NUM_SERVO_CHANNELS);
    if (_foreign_channel >= 0 || memcmp(&p, &_last_params, sizeof(p)) == 0) {
        return;
    }
    _last_params = p;
    WITH_SEMAPHORE(_sem);
    _shared.params = p;
    _shared.new_params = true;
}

void AP_RollMPC::sample_inputs(rollglue_ap_sample &s) const
{
    const AP_AHRS &ahrs = AP::ahrs();
    // the IMU sample behind this attitude, on the 64-bit clock
    const uint32_t imu_age_us = AP_HAL::micros() - AP::ins().get_last_update_usec();
    s.roll_cd = ahrs.roll_sensor;
    s.roll_us = ahrs.healthy() ? AP_HAL::micros64() - imu_age_us : 0;
    s.gyro_x_rads = ahrs.get_gyro().x;
    // the schedule of an airspeed-scheduled controller (c172_roll): the AHRS's equivalent
    // airspeed (sensor or synthetic), none while it has no estimate
    float airspeed_mps;
    const bool have_airspeed = ahrs.airspeed_EAS(airspeed_mps);
    s.airspeed_mps = have_airspeed ? airspeed_mps : NAN;
    s.airspeed_us = have_airspeed ? s.roll_us : 0;
    s.roll_cmd_cd = _cmd_cd;
    s.cmd_us = _cmd_us;
    memcpy(s.applied_scaled, _applied_scaled, sizeof(s.applied_scaled));
    s.engage = _may_fly;
}

void AP_RollMPC::update()
{
    if (_start == Start::NOT_YET && _enable > 0) {
        start();
    }
    if (_start != Start::RUNNING) {
        return;
    }
    if (_samples++ % ROLLGLUE_SAMPLE_HZ == 0) {
        post_params();  // once a second: AP_Param has no change notification
    }
    rollglue_ap_sample s {};
    sample_inputs(s);
    {
        WITH_SEMAPHORE(_sem);
        _shared.sample = s;
        _shared.sample_us = AP_HAL::micros64();
    }
    _wake.signal();
    report();
}

// one sample per wake-up; a sample that arrives while a solve runs replaces the one
// waiting, so the worker always solves the newest
void AP_RollMPC::worker()
{
    while (true) {
        if (!_wake.wait(kWakeTimeoutUs)) {
            continue;
        }
        rollglue_ap_sample s;
        rollglue_params p;
        bool new_params;
        uint64_t sample_us;
        {
            WITH_SEMAPHORE(_sem);
            s = _shared.sample;
            sample_us = _shared.sample_us;
            p = _shared.params;
            new_params = _shared.new_params;
            _shared.new_params = false;
        }
        const int params_result = new_params ? rollglue_set_params(&_glue, &p, NUM_SERVO_CHANNELS)
                                             : ROLLGLUE_PARAMS_OK;
        rollglue_input in;
        rollglue_ap_input(&s, &in);
        rollglue_output out;
        const uint32_t t0_us = AP_HAL::micros();
        rollglue_step(&_glue, &in, AP_HAL::micros64(), &out);
        const uint32_t solve_us = AP_HAL::micros() - t0_us;

        WITH_SEMAPHORE(_sem);
        _shared.out = out;
        _shared.out_sample_us = sample_us;
        _shared.tm = *rollglue_get_telemetry(&_glue);
        if (new_params) {
            _shared.params_result = params_result;
        }
        _shared.solve_us = solve_us;
        _shared.max_solve_us = MAX(_shared.max_solve_us, solve_us);
    }
}

void AP_RollMPC::output()
{
    const bool allowed = _may_fly_this_loop;
    _may_fly_this_loop = false;  // a loop without set_command() hands back
    if (_start != Start::RUNNING) {
        return;
    }
    rollglue_output out;
    uint64_t out_sample_us;
    {
        WITH_SEMAPHORE(_sem);
        out = _shared.out;
        out_sample_us = _shared.out_sample_us;
    }
    const bool use = allowed && out.valid && AP_HAL::micros64() - out_sample_us <= kMaxOutputAgeUs;
    const float own = SRV_Channels::get_output_scaled(SRV_Channel::k_aileron);
    uint32_t driven = 0;
    for (uint8_t c = 0; c < NUM_SERVO_CHANNELS; c++) {
        SRV_Channel *ch = SRV_Channels::srv_channel(c);
        const bool aileron = ch != nullptr && ch->get_function() == SRV_Channel::k_aileron;
        _applied_scaled[c] = aileron ? own : NAN;
        if (!aileron || !use || (out.channel_mask & (1U << c)) == 0) {
            continue;
        }
        // +/-4500 through the channel's own SERVOn_MIN/TRIM/MAX/REVERSED
        const float scaled = rollglue_ap_scaled(out.value[c]);
        ch->set_output_pwm(ch->pwm_from_scaled_value(scaled));
        _applied_scaled[c] = scaled;
        driven |= 1U << c;
    }
    if ((_owned_mask & ~driven) != 0) {
        // hand back: rewriting the function's own value drops the PWM set above
        SRV_Channels::set_output_scaled(SRV_Channel::k_aileron, own);
    }
    _owned_mask = driven;
    if (out_sample_us != _logged_sample_us) {  // one record per worker sample
        _logged_sample_us = out_sample_us;
        log_sample(out, own, driven);
    }
}

// RMPC: who drove the first aileron servo in the loop that used this sample (Use = 1: the
// MPC's value Mpc, else ArduPlane's own Own, both in +/-4500 units), with the glue's state,
// reasons, controller status and mode, the MPC's first deflection and the solve time
void AP_RollMPC::log_sample(const rollglue_output &out, float own, uint32_t driven)
{
#if HAL_LOGGING_ENABLED
    rollglue_telemetry tm;
    uint32_t solve_us;
    {
        WITH_SEMAPHORE(_sem);
        tm = _shared.tm;
        solve_us = _shared.solve_us;
    }
    const int ch = _last_params.channel[0][0];
    const float mpc = (ch >= 0 && out.valid) ? rollglue_ap_scaled(out.value[ch]) : NAN;
    AP::logger().WriteStreaming("RMPC", "TimeUS,Use,Valid,St,Rsn,Stat,Mode,U0,Mpc,Own,Sus",
                                "s---------s", "F---------F", "QBBBHBBfffI",
                                AP_HAL::micros64(), uint8_t(driven != 0), uint8_t(out.valid != 0),
                                uint8_t(tm.state), uint16_t(tm.reasons), uint8_t(tm.status),
                                uint8_t(tm.mode), out.u_deg[0], mpc, own, solve_us);
#else
    (void)out; (void)own; (void)driven;
#endif
}

// at most one text per kMessageIntervalMs, the most important change first; a change not
// reported yet goes out with a later one
void AP_RollMPC::report()
{
    const uint32_t now_ms = AP_HAL::millis();
    if (now_ms - _reported.last_ms < kMessageIntervalMs) {
        return;
    }
    rollglue_telemetry tm;
    int params_result;
    {
        WITH_SEMAPHORE(_sem);
        tm = _shared.tm;
        params_result = _shared.params_result;
    }
    if (tm.state != ROLLGLUE_LOCKOUT) {
        _reported.state = tm.state;
    }
    if (_foreign_channel != _reported.foreign_channel) {
        _reported.foreign_channel = _foreign_channel;
        if (_foreign_channel < 0) {
            return;
        }
        GCS_SEND_TEXT(MAV_SEVERITY_ERROR, "RollMPC: SERVO%d is not an Aileron, RMPC_* not applied",
                      _foreign_channel + 1);
    } else if (params_result != _reported.params_result) {
        _reported.params_result = params_result;
        if (params_result == ROLLGLUE_PARAMS_OK) {
            return;
        }
        const bool known = params_result > 0 && params_result < int(ARRAY_SIZE(kParamNames));
        GCS_SEND_TEXT(MAV_SEVERITY_ERROR, "RollMPC: RMPC_%s out of range, %s",
                      known ? kParamNames[params_result] : "?",
                      (tm.reasons & ROLLGLUE_NO_PARAMS) ? "MPC off" : "previous values kept");
    } else if (tm.state == ROLLGLUE_LOCKOUT && _reported.state != ROLLGLUE_LOCKOUT) {
        _reported.state = tm.state;
        GCS_SEND_TEXT(MAV_SEVERITY_WARNING, "RollMPC: locked out after %u failures in a row",
                      unsigned(tm.consecutive_failures));
    } else if (tm.failures != _reported.failures) {
        _reported.failures = tm.failures;
        GCS_SEND_TEXT(MAV_SEVERITY_WARNING, "RollMPC: handed back (%u failures, now 0x%03x)",
                      unsigned(tm.failures), unsigned(tm.reasons));
    } else if (tm.engagements != _reported.engagements) {
        _reported.engagements = tm.engagements;
        GCS_SEND_TEXT(MAV_SEVERITY_INFO, "RollMPC: engaged (%u)", unsigned(tm.engagements));
    } else {
        return;
    }
    _reported.last_ms = now_ms;
}

#endif  // AP_ROLLMPC_ENABLED
