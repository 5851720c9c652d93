"""Demonstration datasets of ``hsddp_gym/Bounding-v0``: parallel, seeded generation; Minari + npz output.

Generation
----------
[`generate_dataset`][hsddp_gym.datasets.generation.generate_dataset] runs ``episodes`` episodes of a policy, episode
``i`` reset with seed ``seed + i`` and played by a *fresh* policy built for it
([`PolicySpec`][hsddp_gym.rollout.policies.PolicySpec], or any picklable factory ``factory(env, episode_seed) ->
policy``, the policy's ``reset_options`` attribute its episodes' reset options), so an episode depends only on its seed:
the same ``seed`` and ``episodes`` give identical arrays whatever the number of worker processes. Workers are
``spawn``-started processes (`concurrent.futures.ProcessPoolExecutor`; ``workers=1`` runs in this
process); a tqdm bar counts finished episodes.

Built-in policies ([`POLICIES`][hsddp_gym.rollout.policies.POLICIES], built by
[`make_policy`][hsddp_gym.rollout.policies.make_policy]): ``mpc``
([`hsddp_gym.planners.policies.mpc.MPCPolicy`][hsddp_gym.planners.policies.mpc.agent.MPCPolicy], options =
``MPCOptions`` fields), ``expert``
([`hsddp_gym.planners.policies.experts.bounding_expert`][hsddp_gym.planners.policies.experts.bounding_expert] tracking
the HS-DDP plan ``hsddp_gym.planners.tasks.plan_bounding("al-reb", cycles=5).solution``, solved once and stored as
``expert_plan.npz`` in the dataset; every episode is reset with ``options={"state": plan.X[0]}``, i.e. *without* reset
noise, so all expert episodes are identical -- the seed is recorded but has no effect; after the plan's 1.48 s the
default MPC takes over; in the other tasks' envs the task's plan tracker, ``Task.expert`` of the task registry
[`hsddp_gym.registry`][hsddp_gym.registry]), ``heuristic``
([`hsddp_gym.planners.policies.heuristic.HeuristicPolicy`][hsddp_gym.planners.policies.heuristic.HeuristicPolicy]) and
``random``
([`hsddp_gym.planners.policies.random_policy.RandomPolicy`][hsddp_gym.planners.policies.random_policy.RandomPolicy]
seeded with the episode seed).

DART noise injection (``action_noise > 0``, Laskey et al. 2017): the executed actions are the policy's plus
Gaussian noise (seeded by the episode seed), so the episodes visit the states around the policy's
trajectory from which it recovers; the policy's clean actions are stored in ``infos["expert_action"]``
and are the labels
[`hsddp_gym.learning.demonstrations.load_demonstrations`][hsddp_gym.learning.demonstrations.load_demonstrations] uses.

Output (``out`` is one directory, created atomically)
----------------------------------------------------
::

    out/minari/<dataset_id>/data/{main_data.hdf5, metadata.json}   a Minari dataset (MINARI_DATASETS_PATH=out/minari)
    out/episodes.npz       the same data as flat arrays (see [`load_npz`][load_npz]), no pickle
    out/metadata.json      the dataset metadata (also stored in Minari's metadata under "hsddp_gym")
    out/expert_plan.npz    the tracked plan (``expert`` only; ``Solution.load``, hsddp_gym.planners.optimizer.solution)

Load it with ``load_minari(out)`` (sets ``MINARI_DATASETS_PATH`` for the call) or
``MINARI_DATASETS_PATH=out/minari python -c "import minari; minari.load_dataset('<dataset_id>')"``, and
``load_npz(out)``. Everything is written into a hidden sibling ``.<name>.tmp-*`` directory that is renamed
onto ``out`` only when complete: an interrupted or failed run leaves no dataset, never a half-written
``out``. An existing ``out`` is replaced only with ``overwrite=True`` (the old directory is moved aside, the
new one renamed in, the old one deleted).

Resume or refuse: finished episodes are checkpointed into the hidden sibling ``.<name>.partial`` as they
arrive (with the run's settings; deleted once the dataset is published). A rerun with the same settings and
code resumes from them (same data as an uninterrupted run); with other settings it refuses with a message
naming the differences unless ``resume=False`` / ``overwrite=True`` (CLI ``--no-resume`` / ``--overwrite``)
discards them. A run holds a lock there, so two runs never write the same ``out``; temporary directories
of a killed run are removed by the next run.

Per-step data (Minari conventions)
----------------------------------
``observations (T+1, 17)`` float32 (reset observation first), ``actions (T, 4)`` float32 (normalized torques
in [-1, 1]), ``rewards (T,)``, ``terminations (T,)`` (falls), ``truncations (T,)`` (time limit only).

``infos`` has the same keys and shapes at every one of the T+1 rows. **Row t describes observation t**: the
env's info for it (the reset info for t = 0, the info returned by step t-1 after) and the policy's decision
taken at it (for t < T; the last row, where no action is taken, repeats the last decision's values with
``replanned = planner_failed = False``). Keys:

* from the env ([`hsddp_gym.envs.bounding.BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv]): ``qpos (7,)``, ``qvel
(7,)``, ``contact (2,)`` bool
  ``[front, back]``, ``x_position``, ``x_velocity``, ``reward_forward``, ``reward_ctrl``, ``reward_healthy``,
  ``foot_heights (2,)``, ``grf (4,)``, ``time`` (whatever keys the env's reset info has; every step is
  checked against them);
* from the policy ([`DECISION_SCHEMA`][hsddp_gym.datasets.recording.DECISION_SCHEMA]): ``expert_state_nominal (14,)``
x-bar and ``expert_action_nominal (4,)`` u-bar / torque_limit (normalized, not clipped) of the plan knot whose
  feedback law ``u = u-bar + K (x - x-bar)`` produced the action, ``expert_tracking`` (True when it did;
  False also when the policy changed the law's torques afterwards, as the MPC's projection of stance torques that
  would push a foot off the ground does; when no plan acted the nominal holds its last value, zeros before any),
  ``solver_iterations`` (DDP iterations),
  ``solver_converged``, ``max_violation`` (largest constraint violation of the plan: touchdown foot height
  [m], torque [N m], friction and negative normal force [N], each in its own unit) and ``solve_ms`` of the
  latest solve, ``replanned`` (a solve was attempted at this step), ``planner_failed`` (it failed; the old
  plan kept acting); with ``include_gains=True`` also ``expert_feedback_gain (4, 14)`` = K / torque_limit
  (column 0, the trunk x, is zero: the trackers do not feed it back). The MPC fills the solver fields from
  its re-plans; the expert from its single offline solve, then from its fallback MPC's re-plans; policies without a
  planner (heuristic, random, learned) with zeros.
"""

from hsddp_gym.util.lazy import lazy_exports

_EXPORTS = {  # module: the public names it defines
    "collection": (
        "EpisodeTask", "check_condition_kwargs", "checkpoint_path", "collect_episodes", "episode_conditions",
        "load_episode", "make_env",
        "run_episode_task", "save_episode",
    ),
    "generation": (
        "CHECKPOINT_FORMAT", "DatasetResult", "REF_MAX_EPISODES", "REF_MIN_EPISODES", "generate_dataset",
        "mean_random_return", "partial_dir",
    ),
    "recording": (
        "DecisionRecorder", "ENV_ID", "Episode", "GAIN_KEY", "NOISE_STREAM", "NONDETERMINISTIC_INFOS",
        "capture_plan_controls", "check_env_id", "inform_sent_action", "record_episode", "solve_expert_plan",
    ),
    "storage": (
        "FlatDataset", "default_dataset_id", "episodes_to_arrays", "load_minari", "load_npz", "minari_root",
        "read_metadata", "write_dataset",
    ),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
