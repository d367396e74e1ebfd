/**
 * @file RollMpc.hpp
 * @brief PX4 module around the generated roll MPC and the portable glue core
 *        (common/rollglue.h). See firmware_stub/README.md and docs/integration.md.
 *
 * Units live here: PX4 gives radians, rad/s and normalised servo setpoints; the glue
 * takes degrees, deg/s and the same normalised setpoints.
 */
#pragma once

#include <matrix/math.hpp>
#include <drivers/drv_hrt.h>
#include <px4_platform_common/defines.h>
#include <px4_platform_common/module.h>
#include <px4_platform_common/module_params.h>
#include <px4_platform_common/px4_work_queue/ScheduledWorkItem.hpp>
#include <lib/perf/perf_counter.h>
#include <uORB/Publication.hpp>
#include <uORB/Subscription.hpp>
#include <uORB/SubscriptionInterval.hpp>
#include <uORB/topics/actuator_servos.h>
#include <uORB/topics/airspeed_validated.h>
#include <uORB/topics/parameter_update.h>
#include <uORB/topics/rollmpc_servos.h>
#include <uORB/topics/vehicle_angular_velocity.h>
#include <uORB/topics/vehicle_attitude.h>
#include <uORB/topics/vehicle_attitude_setpoint.h>
#include <uORB/topics/vehicle_control_mode.h>
#include <uORB/topics/vehicle_status.h>

#include "rollglue.h"

using namespace time_literals;

#if RMPC_MODULE_DESCRIPTOR /* PX4 main since PR 26476: ModuleBase with a Descriptor */
#define RMPC_MODULE_BASE ModuleBase
#else                      /* v1.15/v1.16: ModuleBase<T> */
#define RMPC_MODULE_BASE ModuleBase<RollMpc>
#endif

class RollMpc final : public RMPC_MODULE_BASE, public ModuleParams, public px4::ScheduledWorkItem
{
public:
	RollMpc();
	~RollMpc() override;

#if RMPC_MODULE_DESCRIPTOR
	static Descriptor desc;
#endif

	/** @see ModuleBase */
	static int task_spawn(int argc, char *argv[]);
	/** @see ModuleBase */
	static int custom_command(int argc, char *argv[]);
	/** @see ModuleBase */
	static int print_usage(const char *reason = nullptr);

	bool init();
	int print_status() override;

	/** Own work queue, one step below nav_and_controllers (fw_rate_control, fw_att_control):
	 *  a long solve delays nothing of theirs. */
	static constexpr px4::wq_config_t kWorkQueue{"wq:rollmpc", 2400, -14};

private:
	void Run() override;

	/** Parameters -> glue; a refused set is reported and the previous one kept. */
	void apply_params();
	void read_inputs();
	void publish(const rollglue_output &out);

	static constexpr float kRadToDeg = 57.295779513082320876f;

	uORB::Subscription _att_sub{ORB_ID(vehicle_attitude)};
	uORB::Subscription _rates_sub{ORB_ID(vehicle_angular_velocity)};
	uORB::Subscription _att_sp_sub{ORB_ID(vehicle_attitude_setpoint)};
	uORB::Subscription _servos_sub{ORB_ID(actuator_servos)};
	uORB::Subscription _airspeed_sub{ORB_ID(airspeed_validated)};
	uORB::Subscription _control_mode_sub{ORB_ID(vehicle_control_mode)};
	uORB::Subscription _status_sub{ORB_ID(vehicle_status)};
	uORB::SubscriptionInterval _parameter_update_sub{ORB_ID(parameter_update), 1_s};
	uORB::Publication<rollmpc_servos_s> _servos_pub{ORB_ID(rollmpc_servos)};

	/* The glue holds the controller instance (~32 KB for N = 100 in float): a member of
	 * the module object, allocated once by task_spawn(), never on the work queue's stack. */
	rollglue _glue{};
	rollglue_input _in{};            ///< latest value and timestamp of every input
	hrt_abstime _att_sample{0};
	bool _attitude_control{false};
	bool _fixed_wing{false};
	bool _params_ok{false};

	perf_counter_t _loop_perf{perf_alloc(PC_ELAPSED, MODULE_NAME": cycle")};
	perf_counter_t _handover_perf{perf_alloc(PC_COUNT, MODULE_NAME": hand-over")};

	DEFINE_PARAMETERS(
		(ParamBool<px4::params::RMPC_EN>) _param_rmpc_en,
		(ParamInt<px4::params::RMPC_TIMEOUT>) _param_rmpc_timeout,
		(ParamInt<px4::params::RMPC_FROZEN>) _param_rmpc_frozen,
		(ParamInt<px4::params::RMPC_WARMUP>) _param_rmpc_warmup,
		(ParamInt<px4::params::RMPC_MAX_FAIL>) _param_rmpc_max_fail,
		(ParamFloat<px4::params::RMPC_SLEW>) _param_rmpc_slew,
		(ParamFloat<px4::params::RMPC_THROW_IN>) _param_rmpc_throw_in,
		(ParamFloat<px4::params::RMPC_THROW_OUT>) _param_rmpc_throw_out,
		(ParamInt<px4::params::RMPC_IN_L>) _param_rmpc_in_l,
		(ParamInt<px4::params::RMPC_IN_R>) _param_rmpc_in_r,
		(ParamInt<px4::params::RMPC_OUT_L>) _param_rmpc_out_l,
		(ParamInt<px4::params::RMPC_OUT_R>) _param_rmpc_out_r,
		(ParamInt<px4::params::RMPC_REV>) _param_rmpc_rev
	)
};
