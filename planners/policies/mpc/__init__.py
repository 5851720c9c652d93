"""HS-DDP model-predictive control, split as MuJoCo MPC splits it.

* [`agent`][hsddp_gym.planners.policies.mpc.agent]: [`MPCPolicy`][hsddp_gym.planners.policies.mpc.agent.MPCPolicy], the
agent: the loop that drives the parts below at the control rate;
* [`state`][hsddp_gym.planners.policies.mpc.state]: the state estimator (filter, sensor bias, action delay, prediction
  over the delay);
* [`schedule`][hsddp_gym.planners.policies.mpc.schedule] and [`clock`][hsddp_gym.planners.policies.mpc.clock]: the
  contact-schedule estimator (the current and next contact phases from the state and the flags);
* [`planner`][hsddp_gym.planners.policies.mpc.planner] and [`warm_start`][hsddp_gym.planners.policies.mpc.warm_start]:
the planner (HS-DDP re-plans, warm starts, restarts);
* [`law`][hsddp_gym.planners.policies.mpc.law]: the policy between re-plans (the latest plan's feedback law);
* [`speed`][hsddp_gym.planners.policies.mpc.speed], [`ground`][hsddp_gym.planners.policies.mpc.ground]: the speed
reference and the ground the plans stand on;
* [`motion`][hsddp_gym.planners.policies.mpc.motion]: the MPC of a planned motion (the backflip), the same parts on
  what remains of the motion;
* [`options`][hsddp_gym.planners.policies.mpc.options]:
[`MPCOptions`][hsddp_gym.planners.policies.mpc.options.MPCOptions]. """

from hsddp_gym.util.lazy import lazy_exports

_EXPORTS = {  # module: the public names it defines
    "agent": ("MPCPolicy",),
    "clock": ("CYCLE", "DOUBLE_STANCE_PHASE", "GaitClock", "stance_elapsed"),
    "ground": ("GroundModel", "env_terrain"),
    "law": ("FeedbackLaw",),
    "motion": ("MotionMPCPolicy", "MotionReference"),
    "options": ("EstimatorOptions", "FAST_BOUNDING_DURATIONS", "MPCOptions", "MotionOptions", "PlanOptions",
                "ReplanOptions", "ScheduleOptions", "SpeedOptions"),
    "planner": ("MPCPlanner", "Plan"),
    "schedule": ("ContactScheduleEstimator", "late_landing"),
    "speed": ("SpeedReference",),
    "state": ("StateEstimator",),
    "warm_start": ("shift_plan",),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
