"""Seeded perturbations of ``hsddp_gym/Bounding-v0`` and of every task's env for robustness tests, usable with any
policy.

* [`wrappers`][hsddp_gym.envs.perturbations.wrappers]: the Gymnasium wrappers: observation noise and bias
  ([`ObservationNoise`][hsddp_gym.envs.perturbations.wrappers.ObservationNoise],
  [`ObservationBias`][hsddp_gym.envs.perturbations.wrappers.ObservationBias]), latency
  ([`ActionDelay`][hsddp_gym.envs.perturbations.wrappers.ActionDelay]), pushes at random times or by contact phase
  ([`RandomPush`][hsddp_gym.envs.perturbations.wrappers.RandomPush],
  [`PhasePush`][hsddp_gym.envs.perturbations.wrappers.PhasePush]), a contact model of the MuJoCo twin drawn per episode
  ([`RandomContactModel`][hsddp_gym.envs.perturbations.wrappers.RandomContactModel]); each draws from its own generator
  seeded from the episode seed, so an episode's perturbation is a function of its seed alone;
* [`conditions`][hsddp_gym.envs.perturbations.conditions]: one registry,
[`CONDITIONS`][hsddp_gym.envs.perturbations.conditions.CONDITIONS], of named conditions (env
  arguments such as ``friction`` and ``trunk_mass_scale`` plus those wrappers): the robustness benchmark's
  ([`SUITE`][hsddp_gym.envs.perturbations.conditions.SUITE], ``experiments/robustness.py``), the contact models
  ([`CONTACT_CONDITIONS`][hsddp_gym.envs.perturbations.conditions.CONTACT_CONDITIONS]) and the conditions of a real
  robot ([`HARDWARE_CONDITIONS`][hsddp_gym.envs.perturbations.conditions.HARDWARE_CONDITIONS]).

Every public name of both modules is importable from ``hsddp_gym.envs.perturbations`` itself (lazily).

Example::

    from hsddp_gym.envs.perturbations import make_env
    env = make_env("push")                    # gym.make("hsddp_gym/Bounding-v0") + RandomPush
    obs, info = env.reset(seed=3)             # info["push"]: the push of this episode
    env = make_env("push", env_id="hsddp_gym/Backflip-v0")  # a push within the flip (the task's window and size)
"""

from hsddp_gym.util.lazy import lazy_exports

_EXPORTS = {  # module: the public names it defines
    "conditions": (
        "CONDITIONS", "CONTACT_CONDITIONS", "ENV_ID", "HARDWARE_CONDITIONS", "PHASE_PUSH_DELTA_V", "SENSOR_BIAS",
        "SENSOR_BIAS_RANGE", "SENSOR_BIAS_X2", "SIMULATORS", "SUITE", "TASK_SUITE", "Condition", "ContactCondition",
        "HardwareCondition", "check_conditions", "condition_task", "get_condition", "make_env", "simulator_env_id",
        "task_push",
    ),
    "wrappers": (
        "CONTACT_SALT", "PUSH_PHASES", "PUSH_SALT", "ActionDelay", "ObservationBias", "ObservationNoise", "PhasePush",
        "PushDistribution", "RandomContactModel", "RandomPush", "episode_generator", "episode_perturbation",
        "observation_entries", "true_observation", "wrapper_info_keys",
    ),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
