/**
 * @file RollMpc.cpp
 * @brief PX4 glue of the generated roll MPC: vehicle_attitude (quaternion -> roll, deg),
 *        vehicle_angular_velocity (rad/s -> deg/s), rollmpc_step() at 100 Hz, normalised
 *        aileron setpoints out; hand-over to the fixed-wing rate controller on a
 *        non-finite output or a non-optimal status.
 */
#include "RollMpc.hpp"

#include <math.h>

RollMpc::RollMpc() :
	ModuleParams(nullptr),
	ScheduledWorkItem(MODULE_NAME, px4::wq_configurations::nav_and_controllers)
{
	rollmpc_init(&_mpc);
}

RollMpc::~RollMpc()
{
	perf_free(_loop_perf);
	perf_free(_fallback_perf);
}

bool RollMpc::init()
{
	/* the controller's sample time is fixed at generation: 10 ms */
	static_assert(ROLLMPC_N_OUTPUTS == 1 && ROLLMPC_N_ACTUATORS == 2, "roll MPC with two pairs");
	ScheduleOnInterval(10_ms);
	return true;
}

void RollMpc::hand_over(const hrt_abstime &timestamp_sample, int status)
{
	rollmpc_ailerons_s out{};
	out.timestamp_sample = timestamp_sample;
	for (float &c : out.control) {
		c = NAN;
	}
	out.valid = false;
	out.status = static_cast<uint8_t>(status);
	out.mode = static_cast<uint8_t>(rollmpc_last_info(&_mpc)->mode);
	out.failsafe_events = _failsafe_events;
	out.timestamp = hrt_absolute_time();
	_ailerons_pub.publish(out);
	perf_count(_fallback_perf);
}

void RollMpc::Run()
{
	if (should_exit()) {
		ScheduleClear();
		exit_and_cleanup();
		return;
	}

	perf_begin(_loop_perf);

	if (_parameter_update_sub.updated()) {
		parameter_update_s pupdate;
		_parameter_update_sub.copy(&pupdate);
		updateParams();
	}

	vehicle_control_mode_s control_mode;
	if (_control_mode_sub.update(&control_mode)) {
		_attitude_control = control_mode.flag_control_attitude_enabled;
	}

	/* units: the controller works in degrees; PX4 in radians */
	hrt_abstime timestamp_sample = 0;
	vehicle_attitude_s att;
	if (_att_sub.update(&att)) {
		_roll_deg = matrix::Eulerf(matrix::Quatf(att.q)).phi() * kRadToDeg;
		timestamp_sample = att.timestamp_sample;
	}

	vehicle_angular_velocity_s rates;
	if (_rates_sub.update(&rates)) {
		_roll_rate_dps = rates.xyz[0] * kRadToDeg;
	}

	vehicle_attitude_setpoint_s att_sp;
	if (_att_sp_sub.update(&att_sp)) {
		_roll_cmd_deg = matrix::Eulerf(matrix::Quatf(att_sp.q_d)).phi() * kRadToDeg;
	}

	if (!_param_rmpc_en.get() || !_attitude_control) {
		if (_engaged) {
			hand_over(timestamp_sample, ROLLMPC_OPTIMAL);
		}
		_engaged = false;
		rollmpc_init(&_mpc); /* observers restart from zero when re-enabled */
		perf_end(_loop_perf);
		return;
	}

	/* no preview source: the command is held over the horizon */
	for (int k = 0; k < ROLLMPC_HORIZON; k++) {
		_ref[k] = static_cast<rollmpc_real>(_roll_cmd_deg);
	}

	const rollmpc_real y[1] {static_cast<rollmpc_real>(_roll_deg)};
	const rollmpc_real sched[1] {static_cast<rollmpc_real>(_roll_rate_dps)};
	const int status = rollmpc_step(&_mpc, y, sched, _ref, _u);

	const bool finite = PX4_ISFINITE(_u[0]) && PX4_ISFINITE(_u[1]);

	if (status != ROLLMPC_OPTIMAL || !finite) {
		++_failsafe_events;
		++_consecutive_failures;
		hand_over(timestamp_sample, status);

		if (_consecutive_failures >= _param_rmpc_max_fail.get()) {
			PX4_WARN("%s: handing over to fw_rate_control", rollmpc_status_message(status));
			_param_rmpc_en.set(false);
			_param_rmpc_en.commit_no_notification();
		}

		perf_end(_loop_perf);
		return;
	}

	_consecutive_failures = 0;
	_engaged = true;

	rollmpc_ailerons_s out{};
	out.timestamp_sample = timestamp_sample;
	for (float &c : out.control) {
		c = NAN;
	}
	/* deg -> normalised [-1, 1] by the servo throw */
	out.control[_param_rmpc_srv_in.get()] = math::constrain(
			static_cast<float>(_u[0]) / _param_rmpc_throw_in.get(), -1.f, 1.f);
	out.control[_param_rmpc_srv_out.get()] = math::constrain(
			static_cast<float>(_u[1]) / _param_rmpc_throw_out.get(), -1.f, 1.f);
	out.valid = true;
	out.status = static_cast<uint8_t>(status);
	out.mode = static_cast<uint8_t>(rollmpc_last_info(&_mpc)->mode);
	out.failsafe_events = _failsafe_events;
	out.solve_cycles = rollmpc_last_info(&_mpc)->solve_ticks;
	out.timestamp = hrt_absolute_time();
	_ailerons_pub.publish(out);

	perf_end(_loop_perf);
}

int RollMpc::task_spawn(int argc, char *argv[])
{
	RollMpc *instance = new RollMpc();

	if (instance) {
		_object.store(instance);
		_task_id = task_id_is_work_queue;

		if (instance->init()) {
			return PX4_OK;
		}

	} else {
		PX4_ERR("alloc failed");
	}

	delete instance;
	_object.store(nullptr);
	_task_id = -1;
	return PX4_ERROR;
}

int RollMpc::print_status()
{
	const rollmpc_info *info = rollmpc_last_info(&_mpc);
	PX4_INFO("engaged %d, mode %d, status %s, failsafe events %u, solve %u cycles",
		 _engaged, info->mode, rollmpc_status_message(info->status),
		 static_cast<unsigned>(_failsafe_events), static_cast<unsigned>(info->solve_ticks));
	perf_print_counter(_loop_perf);
	perf_print_counter(_fallback_perf);
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
Generated roll MPC (rollmpc) for a fixed wing with two aileron pairs. Publishes
normalised aileron setpoints on rollmpc_ailerons; valid = false hands the ailerons back
to fw_rate_control (on RMPC_EN = 0, a non-finite output or a non-optimal status).
)DESCR_STR");

	PRINT_MODULE_USAGE_NAME("rollmpc", "controller");
	PRINT_MODULE_USAGE_COMMAND("start");
	PRINT_MODULE_USAGE_DEFAULT_COMMANDS();
	return 0;
}

extern "C" __EXPORT int rollmpc_main(int argc, char *argv[])
{
	return RollMpc::main(argc, argv);
}
