/**
 * @file RollMpc.cpp
 * @brief PX4 glue of the generated roll MPC: vehicle_attitude (quaternion -> roll, deg),
 *        vehicle_angular_velocity (rad/s -> deg/s) and the roll of
 *        vehicle_attitude_setpoint in, the glue core (freshness, warm observers,
 *        bumpless engage, failure counting, servo mapping), rollmpc_servos out to the
 *        patched control allocator. The module never writes a parameter.
 */
#include "RollMpc.hpp"

#include <limits.h>
#include <math.h>

#if RMPC_MODULE_DESCRIPTOR
ModuleBase::Descriptor RollMpc::desc{task_spawn, custom_command, print_usage};
#define RMPC_OBJECT desc.object
#define RMPC_TASK_ID desc.task_id
#define RMPC_EXIT_AND_CLEANUP() exit_and_cleanup(desc)
#define RMPC_MAIN(argc, argv) ModuleBase::main(RollMpc::desc, argc, argv)
#else
#define RMPC_OBJECT _object
#define RMPC_TASK_ID _task_id
#define RMPC_EXIT_AND_CLEANUP() exit_and_cleanup()
#define RMPC_MAIN(argc, argv) RollMpc::main(argc, argv)
#endif

static_assert(ROLLGLUE_N_ACT == 1 || ROLLGLUE_N_ACT == 2,
	      "one or two aileron pairs: inner (RMPC_IN_*), outer (RMPC_OUT_*)");
static_assert(actuator_servos_s::NUM_CONTROLS <= sizeof(rollmpc_servos_s::control) / sizeof(float),
	      "rollmpc_servos must cover every servo");

/* Out-of-range values map to one the glue refuses (never a silent wrap-around). */
static uint16_t narrow_u16(int32_t v) { return (v >= 0 && v <= UINT16_MAX) ? static_cast<uint16_t>(v) : UINT16_MAX; }
static int8_t narrow_i8(int32_t v) { return (v >= INT8_MIN && v <= INT8_MAX) ? static_cast<int8_t>(v) : INT8_MAX; }

RollMpc::RollMpc() :
	ModuleParams(nullptr),
	ScheduledWorkItem(MODULE_NAME, kWorkQueue)
{
	rollglue_cycles_enable();
	rollglue_init(&_glue);
}

RollMpc::~RollMpc()
{
	perf_free(_loop_perf);
	perf_free(_handover_perf);
}

bool RollMpc::init()
{
	apply_params();
	ScheduleOnInterval(1000000U / ROLLGLUE_SAMPLE_HZ); // us: the controller's sample time, fixed at generation
	return true;
}

void RollMpc::apply_params()
{
	rollglue_params p{};
	p.timeout_us = static_cast<uint32_t>(narrow_u16(_param_rmpc_timeout.get())) * 1000u;
	p.frozen_samples = narrow_u16(_param_rmpc_frozen.get());
	p.warmup_samples = narrow_u16(_param_rmpc_warmup.get());
	p.max_failures = narrow_u16(_param_rmpc_max_fail.get());
	p.ref_slew_dps = _param_rmpc_slew.get();
	/* a one-actuator controller (e.g. c172_roll) uses the inner pair's parameters only */
	const float throw_deg[2] {_param_rmpc_throw_in.get(), _param_rmpc_throw_out.get()};
	const int32_t servo[2][2] {{_param_rmpc_in_l.get(), _param_rmpc_in_r.get()},
		{_param_rmpc_out_l.get(), _param_rmpc_out_r.get()}};
	const int32_t rev = _param_rmpc_rev.get();

	for (int a = 0; a < ROLLGLUE_N_ACT; a++) {
		p.throw_deg[a] = throw_deg[a];

		for (int s = 0; s < 2; s++) {
			p.channel[a][s] = narrow_i8(servo[a][s]);
			p.sign[a][s] = (rev & (1 << (2 * a + s))) ? -1 : 1;
		}
	}

	const int result = rollglue_set_params(&_glue, &p, actuator_servos_s::NUM_CONTROLS);

	if (result != ROLLGLUE_PARAMS_OK) {
		PX4_ERR("RMPC_* out of range (rollglue_params_result %d): %s", result,
			_params_ok ? "keeping the previous set" : "not flying");

	} else {
		_params_ok = true;
	}
}

void RollMpc::read_inputs()
{
	vehicle_control_mode_s control_mode;

	if (_control_mode_sub.update(&control_mode)) {
		_attitude_control = control_mode.flag_control_attitude_enabled;
	}

	vehicle_status_s status;

	if (_status_sub.update(&status)) {
		_fixed_wing = status.vehicle_type == vehicle_status_s::VEHICLE_TYPE_FIXED_WING;
	}

	/* units: PX4 radians -> the controller's degrees; timestamps: the sample's own */
	vehicle_attitude_s att;

	if (_att_sub.update(&att)) {
		_in.roll_deg = matrix::Eulerf(matrix::Quatf(att.q)).phi() * kRadToDeg;
		_in.roll_us = att.timestamp_sample;
		_att_sample = att.timestamp_sample;
	}

	vehicle_angular_velocity_s rates;

	if (_rates_sub.update(&rates)) {
		_in.roll_rate_dps = rates.xyz[0] * kRadToDeg;
		_in.rate_us = rates.timestamp_sample;
	}

	vehicle_attitude_setpoint_s att_sp;

	if (_att_sp_sub.update(&att_sp)) {
		_in.roll_cmd_deg = matrix::Eulerf(matrix::Quatf(att_sp.q_d)).phi() * kRadToDeg;
		_in.cmd_us = att_sp.timestamp;
	}

	/* the schedule of an airspeed-scheduled controller (c172_roll): calibrated airspeed */
	airspeed_validated_s airspeed;

	if (_airspeed_sub.update(&airspeed)) {
		_in.airspeed_mps = airspeed.calibrated_airspeed_m_s;
		_in.airspeed_us = airspeed.timestamp;
	}

	/* what the servos get now (the allocator's values, ours when engaged): the observers
	 * follow the aircraft on it while fw_rate_control flies */
	actuator_servos_s servos;

	if (_servos_sub.update(&servos)) {
		for (int i = 0; i < ROLLGLUE_MAX_CHANNELS; i++) {
			_in.applied[i] = i < actuator_servos_s::NUM_CONTROLS ? servos.control[i] : NAN;
		}
	}

	_in.engage = _param_rmpc_en.get() && _attitude_control && _fixed_wing;
}

void RollMpc::publish(const rollglue_output &out)
{
	const rollglue_telemetry *tm = rollglue_get_telemetry(&_glue);
	rollmpc_servos_s msg{};
	msg.timestamp_sample = _att_sample;

	for (int i = 0; i < actuator_servos_s::NUM_CONTROLS; i++) {
		msg.control[i] = out.value[i];
	}

	for (int i = actuator_servos_s::NUM_CONTROLS; i < static_cast<int>(sizeof(msg.control) / sizeof(float)); i++) {
		msg.control[i] = NAN;
	}

	msg.channel_mask = static_cast<uint16_t>(out.channel_mask);
	msg.valid = out.valid != 0;
	msg.state = static_cast<uint8_t>(tm->state);
	msg.reasons = static_cast<uint16_t>(tm->reasons);
	msg.status = static_cast<uint8_t>(tm->status);
	msg.mode = static_cast<uint8_t>(tm->mode);
	msg.failures = tm->failures;
	msg.solve_cycles = tm->solve_cycles;
	msg.timestamp = hrt_absolute_time();
	_servos_pub.publish(msg);
}

void RollMpc::Run()
{
	if (should_exit()) {
		ScheduleClear();
		RMPC_EXIT_AND_CLEANUP();
		return;
	}

	perf_begin(_loop_perf);

	if (_parameter_update_sub.updated()) {
		parameter_update_s pupdate;
		_parameter_update_sub.copy(&pupdate);
		updateParams();
		apply_params();
	}

	read_inputs();
	const uint32_t failures = rollglue_get_telemetry(&_glue)->failures;
	rollglue_output out;
	rollglue_step(&_glue, &_in, hrt_absolute_time(), &out);

	if (rollglue_get_telemetry(&_glue)->failures != failures) {
		perf_count(_handover_perf);
	}

	publish(out);
	perf_end(_loop_perf);
}

int RollMpc::task_spawn(int argc, char *argv[])
{
	RollMpc *instance = new RollMpc();

	if (instance) {
		RMPC_OBJECT.store(instance);
		RMPC_TASK_ID = task_id_is_work_queue;

		if (instance->init()) {
			return PX4_OK;
		}

	} else {
		PX4_ERR("alloc failed");
	}

	delete instance;
	RMPC_OBJECT.store(nullptr);
	RMPC_TASK_ID = -1;
	return PX4_ERROR;
}

int RollMpc::print_status()
{
	const rollglue_telemetry *tm = rollglue_get_telemetry(&_glue);
	PX4_INFO("state %d, reasons 0x%03x, mode %d, status %s", tm->state, static_cast<unsigned>(tm->reasons),
		 tm->mode, ROLLGLUE_FN(_status_message)(tm->status));
	PX4_INFO("engagements %u, failures %u, solve %u cycles (max %u)", static_cast<unsigned>(tm->engagements),
		 static_cast<unsigned>(tm->failures), static_cast<unsigned>(tm->solve_cycles),
		 static_cast<unsigned>(tm->max_solve_cycles));
	perf_print_counter(_loop_perf);
	perf_print_counter(_handover_perf);
	return 0;
}

int RollMpc::custom_command(int argc, char *argv[])
{
	return print_usage("unknown command");
}

int RollMpc::print_usage(const char *reason)
{
	if (reason) {
		PX4_WARN("%s\n", reason);
	}

	PRINT_MODULE_DESCRIPTION(
		R"DESCR_STR(
### Description
Generated roll MPC (rollmpc) for a fixed wing with two aileron pairs, 100 Hz in its own
work queue. Publishes rollmpc_servos; the patched control allocator puts those values on
the aileron servos while they are valid and fresh, and fw_rate_control keeps every servo
otherwise (RMPC_EN = 0, no attitude control, stale/frozen/NaN input, a failed solve).
)DESCR_STR");

	PRINT_MODULE_USAGE_NAME("rollmpc", "controller");
	PRINT_MODULE_USAGE_COMMAND("start");
	PRINT_MODULE_USAGE_DEFAULT_COMMANDS();
	return 0;
}

extern "C" __EXPORT int rollmpc_main(int argc, char *argv[])
{
	return RMPC_MAIN(argc, argv);
}
