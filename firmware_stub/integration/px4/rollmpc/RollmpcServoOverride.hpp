/**
 * @file RollmpcServoOverride.hpp
 * @brief The control allocator's side of the rollmpc servo path (control_allocator.patch):
 *        the module's per-servo values replace the allocator's on the servos it owns,
 *        while they are valid and fresh. Everything else (motors, elevator, rudder,
 *        flaps, the other servos) stays with control allocation.
 */
#pragma once

#include <drivers/drv_hrt.h>
#include <px4_platform_common/defines.h>
#include <uORB/Subscription.hpp>
#include <uORB/topics/actuator_servos.h>
#include <uORB/topics/rollmpc_servos.h>

class RollmpcServoOverride
{
public:
	/** Two samples of the 100 Hz module: older values are ignored. */
	static constexpr hrt_abstime kMaxAgeUs = 20000;

	/** Replace the owned servos' setpoints in place; the caller then publishes. */
	void apply(actuator_servos_s &servos)
	{
		rollmpc_servos_s s;

		if (!_sub.copy(&s) || !s.valid || hrt_elapsed_time(&s.timestamp) > kMaxAgeUs) {
			return;
		}

		static_assert(actuator_servos_s::NUM_CONTROLS <= sizeof(s.control) / sizeof(s.control[0]),
			      "rollmpc_servos must cover every servo");

		for (int i = 0; i < actuator_servos_s::NUM_CONTROLS; i++) {
			if ((s.channel_mask & (1u << i)) && PX4_ISFINITE(s.control[i])) {
				servos.control[i] = s.control[i];
			}
		}
	}

private:
	uORB::Subscription _sub{ORB_ID(rollmpc_servos)};
};
