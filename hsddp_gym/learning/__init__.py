"""Learning: behaviour cloning and DAgger in plain PyTorch (no ``imitation`` dependency), and the SB3 RL baselines
([`hsddp_gym.learning.sb3`][hsddp_gym.learning.sb3]).

**Behaviour cloning** ([`train_bc`][hsddp_gym.learning.bc.train_bc], defaults in
[`BCConfig`][hsddp_gym.learning.bc.BCConfig]): an MLP ``obs -> action`` with two hidden layers of 256 ReLU units and a
tanh output (the env's actions are normalized torques in [-1, 1]), trained with Adam (lr 1e-3, batch 256, no weight
decay) on the mean squared error to the demonstrated normalized actions, for ``epochs`` passes over the data.
Observations are standardized with the mean and standard deviation of the training data (std floored at 1e-3, result
clipped to +-10, as SB3's VecNormalize). ``lr_decay`` anneals the step with a cosine schedule to 0 over the epochs.
Seeded: ``torch.manual_seed(seed)`` for the initialization and a seeded generator for the
minibatch order, one CPU thread, so a run is reproducible.

The trained policy is an [`MLPPolicy`][hsddp_gym.learning.bc.MLPPolicy], a
[`Policy`][hsddp_gym.planners.policies.base.Policy] whose inference is NumPy only (no torch at evaluation), saved as
``.npz`` (weights + normalization + config as JSON; loading never unpickles).

**Inputs** (``BCConfig.features``): ``"obs"`` (default) feeds the observation; ``"gait_clock"`` appends the
7 features of the MPC's gait clock
([`hsddp_gym.planners.policies.mpc.GaitClock`][hsddp_gym.planners.policies.mpc.clock.GaitClock]: phase one-hot, time in
phase, cycle sin/cos). The MPC's phase is advanced by the observed touchdowns and drifts from the observation's clock
``2 pi t / gait_period`` (about 0.2 cycles per second, a whole cycle over a 5 s episode), so its action is not a
function of the observation alone; the clock, however, is a deterministic function of the observation history (contact
flags, pitch rate, step count), which [`MLPPolicy`][hsddp_gym.learning.bc.MLPPolicy] replays while acting (it then has
memory, cleared by ``reset()``) and [`build_inputs`][hsddp_gym.learning.features.build_inputs] replays per demonstration
episode. With ``BCConfig.speed_input`` the env's target speed [m/s] is one more input (the observation does not hold
it): the demonstrations' from their datasets' metadata (demonstrations at several speeds:
``load_demonstrations([dir, ...])``, ``hsddp-gym train --dataset DIR DIR ... --speed-input``), the env's
``EnvInterface.target_speed`` while acting.

**Feedback-gain labels** (``BCConfig.gain_copies``, [`hsddp_gym.learning.gain_labels`][hsddp_gym.learning.gain_labels]):
from a dataset recorded with the expert's gains, perturbed copies of every demonstration labelled with the expert's
local law ``u + K dx``.

**Residual RL** ([`hsddp_gym.learning.residual`][hsddp_gym.learning.residual], ``train_sb3(..., residual_scale=)``):
PPO or SAC learn a bounded correction to the task's plan-tracking expert, on the task's own reward.

**Demonstrations** ([`load_demonstrations`][hsddp_gym.learning.demonstrations.load_demonstrations]) come from a Minari
dataset (``minari.load_dataset`` / [`hsddp_gym.datasets.storage.load_minari`][hsddp_gym.datasets.storage.load_minari],
the default) or from a dataset's ``episodes.npz``
([`hsddp_gym.datasets.storage.load_npz`][hsddp_gym.datasets.storage.load_npz]): pairs (observation t, action t) of the
first ``episodes`` episodes; for datasets recorded with DART noise injection (``hsddp-gym dataset --action-noise``) the
label is the expert's clean action ``infos["expert_action"]``, not the noisy executed one.

**DAgger** ([`train_dagger`][hsddp_gym.learning.dagger.train_dagger], Ross et al. 2011): round 0 trains BC on the
initial demonstrations (or on ``episodes_per_round`` expert episodes if none are given). In round ``i >= 1`` the
executed action is the expert's with probability ``beta_i = beta_decay ** i`` and the learner's otherwise (drawn per
step from a seeded generator); the expert runs *alongside* on the same env states for the whole episode -- it is
queried at every visited observation, so a policy with memory (gait clock, plan cursor, MPC warm start)
keeps its memory consistent -- and its action is the label of that observation. The labels are added to the
aggregate data and BC is retrained from scratch on it (or, with ``warm_start``, fine-tuned from the previous
round's network). ``rollout_noise`` adds DART-style Gaussian noise to the executed actions of rounds
``>= 1`` (labels stay clean); ``rollout_steps`` truncates their rollouts. ``expert_labels`` counts every
expert label used for training (the initial demonstrations' actions included).
"""

from hsddp_gym.util.lazy import lazy_exports

_EXPORTS = {  # module: the public names it defines
    "bc": ("ACTIVATIONS", "BCConfig", "MLPPolicy", "run_bc", "train_bc",),
    "dagger": ("DAggerConfig", "DAggerResult", "dagger_rollout", "run_dagger", "train_dagger",),
    "demonstrations": ("Demonstrations", "load_demonstrations",),
    "features": ("FEATURES", "build_inputs", "gait_clock_features", "make_gait_clock",),
    "reporting": ("evaluate_policy_episodes", "plot_curve",),
    "residual": ("ResidualEnv", "ResidualPolicy", "residual_action", "residual_observation",),
    "sb3.adapter": ("as_sb3_policy",),
    "sb3.presets": ("ALGOS", "ENV_ID", "hyperparameters",),
    "sb3.runs": ("SB3ModelPolicy", "load_trained_policy", "write_curves",),
    "sb3.training": ("TrainResult", "save_vecnormalize_npz", "train_sb3",),
    "vector_sb3": ("make_sb3_vec_env",),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
