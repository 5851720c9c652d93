"""Seeded perturbations of ``hsddp_gym/Bounding-v0`` for robustness tests, usable with any policy.

Gymnasium wrappers and env arguments (:mod:`hsddp_gym.envs.perturbations.wrappers`), and one registry,
:data:`CONDITIONS` (:mod:`hsddp_gym.envs.perturbations.conditions`), that names the conditions of the robustness
benchmark (:data:`SUITE`, ``experiments/robustness.py``) and a few more:

* :class:`ObservationNoise`: zero-mean Gaussian noise on the observed positions and velocities (the contact
  flags and the gait clock stay clean);
* :class:`ObservationBias`: a constant offset on named observed positions and velocities (a sensor bias), fixed
  or drawn per episode;
* :class:`ActionDelay`: every action is executed ``steps`` control steps after the policy returned it (the
  first ``steps`` executed actions are zero torques); the wrapper's ``action_delay_steps`` attribute tells a
  policy its latency (:class:`hsddp_gym.planners.policies.base.EnvInterface` reads it), which may differ from the
  executed one (``announced``), and the executed delay may be drawn per episode (``jitter``);
* :class:`RandomPush`: one push (or ``count``) per episode at a random time, a random trunk-velocity change
  ``[dvx, dvz, dpitch_rate]`` (a :class:`PushDistribution`) applied through the env's documented ``push`` reset
  option (the compiled vector env draws the same pushes for its robots with its ``push`` argument);
* :class:`PhasePush`: one such push at the first control step in flight (or in stance) after a random time,
  through the env's ``apply_push``;
* model mismatch through env arguments: ``friction`` (Coulomb coefficient) and ``trunk_mass_scale`` (the
  simulated trunk is heavier or lighter than the model every policy uses);
* contact models the policies were not built on (:class:`ContactCondition`, always in the MuJoCo twin): a corner
  of :data:`hsddp_gym.envs.mujoco_twin.CONTACT_CORNERS` (``contact_<corner>``), or :class:`RandomContactModel`, a
  :class:`~hsddp_gym.envs.mujoco_twin.ContactModel` drawn per episode from the episode seed (``contact_family``).
  They are extra conditions, not in :data:`SUITE`;
* conditions a real robot has (:class:`HardwareCondition`, :data:`HARDWARE_CONDITIONS`): a latency other than the
  announced one, a sensor bias, a push in flight or in stance. Extra conditions too.

**Seeding.** Each wrapper draws from its own generator, seeded at every ``reset(seed=s)`` from ``(s, salt)``
(a per-wrapper constant), so an episode's perturbation is a function of its seed alone, independent of the
policy and of the env's own reset noise; ``reset()`` without a seed continues the generator (seeded from
the env's ``np_random`` on first use).

Every name above is importable from ``hsddp_gym.envs.perturbations`` itself (lazily; the wrappers are defined in
:mod:`~hsddp_gym.envs.perturbations.wrappers`, the registry in :mod:`~hsddp_gym.envs.perturbations.conditions`).

Example::

    from hsddp_gym.envs.perturbations import make_env
    env = make_env("push")                    # gym.make("hsddp_gym/Bounding-v0") + RandomPush
    obs, info = env.reset(seed=3)             # info["push"]: the push of this episode
"""

from hsddp_gym.util.lazy import lazy_exports

_EXPORTS = {  # module: the public names it defines
    "conditions": (
        "CONDITIONS", "CONTACT_CONDITIONS", "ENV_ID", "HARDWARE_CONDITIONS", "PHASE_PUSH_DELTA_V", "SENSOR_BIAS",
        "SENSOR_BIAS_RANGE", "SENSOR_BIAS_X2", "SIMULATORS", "SUITE", "Condition", "ContactCondition",
        "HardwareCondition", "check_conditions", "get_condition", "make_env",
    ),
    "wrappers": (
        "CONTACT_SALT", "PUSH_PHASES", "PUSH_SALT", "ActionDelay", "ObservationBias", "ObservationNoise", "PhasePush",
        "PushDistribution", "RandomContactModel", "RandomPush", "episode_generator", "episode_perturbation",
        "observation_entries", "true_observation", "wrapper_info_keys",
    ),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
