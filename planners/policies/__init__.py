"""Policies that act on ``hsddp_gym/Bounding-v0`` from observations only.

Every policy here is

* a plain callable ``policy(obs) -> action`` for one environment (``obs`` ``(obs_dim,)``, ``action`` ``(4,)``
  float32 normalized torques in ``[-1, 1]``), with its own memory (``reset()`` starts a new episode);
* a Stable-Baselines3 ``predict(observation, state=None, episode_start=None, deterministic=True) ->
  (actions, state)`` predictor (batched ``(n_envs, obs_dim)`` in, ``(n_envs, 4)`` out; one independent copy
  of the policy per environment, reset where ``episode_start`` is true), so ``evaluate_policy`` runs it;
* convertible into an SB3 ``BasePolicy`` with
[`hsddp_gym.learning.sb3.as_sb3_policy`][hsddp_gym.learning.sb3.adapter.as_sb3_policy] for imitation tooling.

Policies never look inside the simulator: they map the observation back to a state, contact mode and gait
phase with [`hsddp_gym.core.observation.state_from_observation`][hsddp_gym.core.observation.state_from_observation] and
use the env's public settings (control period, torque limit, observation layout) given at construction
(``Policy.from_env(env)`` reads them). """

from hsddp_gym.util.lazy import lazy_exports

_EXPORTS = {  # module: the public names it defines
    "base": ("EnvInterface", "Policy",),
    "contact_consistency": ("PushingTorques",),
    "estimated_state": ("EstimatedStatePolicy", "EstimationOptions",),
    "experts": ("backflip_expert", "bounding_expert", "jump_expert", "pronking_expert", "transition_expert",),
    "heuristic": (
        "ContactEventBoundingController", "ContactEventGains", "HeuristicBoundingController", "HeuristicGains",
        "HeuristicPolicy",
    ),
    "mpc": (
        "DOUBLE_STANCE_PHASE", "FAST_BOUNDING_DURATIONS", "GaitClock", "MPCOptions", "MPCPolicy",
    ),
    "random_policy": ("RandomPolicy",),
    "touchdown": ("ContactFlags", "FootClearance", "SeenAirborne", "TouchdownRule", "plan_clearance",),
    "tracking": ("PlanTracker", "tracking_error",),
    "tracking_policy": ("HandOver", "HoldPosture", "PlanTrackingPolicy", "RepeatCycle",),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
