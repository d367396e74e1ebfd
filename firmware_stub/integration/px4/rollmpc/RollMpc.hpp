/**
 * @file RollMpc.hpp
 * @brief PX4 module around the generated roll MPC (reference template, see README).
 *
 * Units live here, not in the controller: PX4 gives radians and rad/s, the controller
 * works in degrees and deg/s, and the aileron setpoints go out normalised to [-1, 1].
 */
#pragma once

#include <matrix/math.hpp>
#include <px4_platform_common/defines.h>
#include <px4_platform_common/module.h>
#include <px4_platform_common/module_params.h>
#include <px4_platform_common/px4_work_queue/ScheduledWorkItem.hpp>
#include <lib/perf/perf_counter.h>
#include <uORB/Publication.hpp>
#include <uORB/Subscription.hpp>
#include <uORB/SubscriptionInterval.hpp>
#include <uORB/topics/parameter_update.h>
#include <uORB/topics/rollmpc_ailerons.h>
#include <uORB/topics/vehicle_angular_velocity.h>
#include <uORB/topics/vehicle_attitude.h>
#include <uORB/topics/vehicle_attitude_setpoint.h>
#include <uORB/topics/vehicle_control_mode.h>

#include "rollmpc.h"

using namespace time_literals;

class RollMpc final : public ModuleBase<RollMpc>, public ModuleParams, public px4::ScheduledWorkItem
{
public:
	RollMpc();
	~RollMpc() override;

	/** @see ModuleBase */
	static int task_spawn(int argc, char *argv[]);
	/** @see ModuleBase */
	static int custom_command(int argc, char *argv[]);
	/** @see ModuleBase */
	static int print_usage(const char *reason = nullptr);

	bool init();
	int print_status() override;

private:
	void Run() override;

	/** Publish invalid setpoints: the fixed-wing rate controller keeps the ailerons. */
	void hand_over(const hrt_abstime &timestamp_sample, int status);

	static constexpr float kRadToDeg = 57.295779513082320876f;

	uORB::Subscription _att_sub{ORB_ID(vehicle_attitude)};
	uORB::Subscription _rates_sub{ORB_ID(vehicle_angular_velocity)};
	uORB::Subscription _att_sp_sub{ORB_ID(vehicle_attitude_setpoint)};
	uORB::Subscription _control_mode_sub{ORB_ID(vehicle_control_mode)};
	uORB::SubscriptionInterval _parameter_update_sub{ORB_ID(parameter_update), 1_s};
	uORB::Publication<rollmpc_ailerons_s> _ailerons_pub{ORB_ID(rollmpc_ailerons)};

	/* The controller instance (~32 KB for N = 100 in float) is a member of the module
	 * object, allocated once by task_spawn(), never on the work queue's stack. */
	rollmpc_ctrl _mpc{};
	rollmpc_real _ref[ROLLMPC_HORIZON * ROLLMPC_N_OUTPUTS] {};
	rollmpc_real _u[ROLLMPC_N_ACTUATORS] {};

	float _roll_deg{0.f};
	float _roll_rate_dps{0.f};
	float _roll_cmd_deg{0.f};
	bool _attitude_control{false};
	bool _engaged{false};
	int _consecutive_failures{0};
	uint32_t _failsafe_events{0};

	perf_counter_t _loop_perf{perf_alloc(PC_ELAPSED, MODULE_NAME": cycle")};
	perf_counter_t _fallback_perf{perf_alloc(PC_COUNT, MODULE_NAME": fallback")};

	DEFINE_PARAMETERS(
		(ParamBool<px4::params::RMPC_EN>) _param_rmpc_en,
		(ParamFloat<px4::params::RMPC_THROW_IN>) _param_rmpc_throw_in,
		(ParamFloat<px4::params::RMPC_THROW_OUT>) _param_rmpc_throw_out,
		(ParamInt<px4::params::RMPC_SRV_IN>) _param_rmpc_srv_in,
		(ParamInt<px4::params::RMPC_SRV_OUT>) _param_rmpc_srv_out,
		(ParamInt<px4::params::RMPC_MAX_FAIL>) _param_rmpc_max_fail
	)
};
