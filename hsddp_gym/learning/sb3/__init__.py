"""Stable-Baselines3 glue: any policy as an SB3 ``BasePolicy``, and the PPO / SAC baselines on ``Bounding-v0`` (and
the other tasks, ``env_id``).

* :mod:`~hsddp_gym.learning.sb3.adapter`: :func:`as_sb3_policy`, a planner policy (or any callable) as an SB3
  ``BasePolicy`` for SB3's and ``imitation``'s tooling;
* :mod:`~hsddp_gym.learning.sb3.presets`: the envs and algorithms the baselines train, the RL-Zoo presets
  (:data:`PRESETS`), the overrides the front-ends offer (:func:`hyperparameters`, gSDE, the learning-rate notation);
* :mod:`~hsddp_gym.learning.sb3.training`: :func:`train_sb3`, a PPO or SAC run and the files it writes;
* :mod:`~hsddp_gym.learning.sb3.runs`: a run's files read back: its curves (:func:`write_curves`) and its policy
  (:func:`load_trained_policy`, :class:`SB3ModelPolicy`, without unpickling).

Every name below is importable from ``hsddp_gym.learning.sb3`` itself (lazily: importing it loads neither SB3 nor
torch).
"""

from hsddp_gym.util.lazy import lazy_exports

_EXPORTS = {  # module: the public names it defines
    "adapter": ("as_sb3_policy",),
    "presets": (
        "ALGOS", "DEFAULT_PRESET", "ENV_ID", "ENV_IDS", "OPTION_HELP", "PPO_HOPPER_HYPERPARAMS", "PPO_HYPERPARAMS",
        "PPO_PARALLEL_HYPERPARAMS", "PRESETS", "SAC_HYPERPARAMS", "SDE_HYPERPARAMS", "SDE_LOG_STD_INIT",
        "TRAINER_KEYS", "hyperparameters", "learning_rate_schedule", "model_kwargs", "parse_learning_rate",
    ),
    "runs": ("BEST_MODEL", "BEST_VECNORMALIZE", "CHECKPOINTS", "SB3ModelPolicy", "load_trained_policy", "read_monitor",
             "write_curves"),
    "training": ("TrainResult", "check_env_id", "check_train_condition", "save_vecnormalize_npz", "train_sb3"),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
