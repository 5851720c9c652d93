"""Stable-Baselines3 glue: any policy as an SB3 ``BasePolicy``, and the PPO / SAC baselines on ``Bounding-v0`` (and
the other tasks, ``env_id``).

* [`adapter`][hsddp_gym.learning.sb3.adapter]: [`as_sb3_policy`][hsddp_gym.learning.sb3.adapter.as_sb3_policy], a
planner policy (or any callable) as an SB3
  ``BasePolicy`` for SB3's and ``imitation``'s tooling;
* [`presets`][hsddp_gym.learning.sb3.presets]: the envs and algorithms the baselines train, the RL-Zoo presets
  ([`PRESETS`][hsddp_gym.learning.sb3.presets.PRESETS]), the overrides the front-ends offer
  ([`hyperparameters`][hsddp_gym.learning.sb3.presets.hyperparameters], gSDE, the learning-rate notation);
* [`training`][hsddp_gym.learning.sb3.training]: [`train_sb3`][hsddp_gym.learning.sb3.training.train_sb3], a PPO or SAC
run and the files it writes;
* [`runs`][hsddp_gym.learning.sb3.runs]: a run's files read back: its curves
([`write_curves`][hsddp_gym.learning.sb3.runs.write_curves]) and its policy
  ([`load_trained_policy`][hsddp_gym.learning.sb3.runs.load_trained_policy],
  [`SB3ModelPolicy`][hsddp_gym.learning.sb3.runs.SB3ModelPolicy], without unpickling).

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
