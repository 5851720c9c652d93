"""Recording one episode: the policies by name, the expert's plan, per-step decisions (the dataset schema)."""

from __future__ import annotations

import contextlib
import dataclasses
import time

import numpy as np

from hsddp_gym.core.conventions import NU, NX
from hsddp_gym.registry import DATASET_ENVS, TASKS, task_of_env_id
from hsddp_gym.util.validation import check_positive

ENV_ID = TASKS["bounding"].env_id
"""The default env of datasets (Bounding-v0)."""
NOISE_STREAM = 7919
"""First entry of the seed sequence of the DART action noise (``[NOISE_STREAM, episode seed]``)."""
NONDETERMINISTIC_INFOS = ("solve_ms",)
"""``infos`` keys that hold wall-clock times: the only data that differ between runs with the same seed."""

DECISION_SCHEMA: dict[str, tuple[tuple, str]] = {
    "expert_state_nominal": ((NX,), "float64"),
    "expert_action_nominal": ((NU,), "float64"),
    "expert_tracking": ((), "bool"),
    "solver_iterations": ((), "int64"),
    "solver_converged": ((), "bool"),
    "max_violation": ((), "float64"),
    "solve_ms": ((), "float64"),
    "replanned": ((), "bool"),
    "planner_failed": ((), "bool"),
}
"""Shape and dtype of the policy-decision keys of ``infos`` (see the module docstring)."""
GAIN_KEY = "expert_feedback_gain"


def check_env_id(env_id) -> str:
    """``env_id`` (None: [`ENV_ID`][ENV_ID]) if it is one of [`DATASET_ENVS`][DATASET_ENVS], else ``ValueError`` naming
    it."""
    if env_id is None:
        return ENV_ID
    if env_id not in DATASET_ENVS:
        raise ValueError(f"env_id must be one of {DATASET_ENVS}, got {env_id!r}")
    return str(env_id)


def solve_expert_plan(path, env_id: str | None = None, target_speed: float = 1.0, hold: int = 5) -> dict:
    """Solve the plan of the expert of ``env_id``'s task (``Task.plan`` of the task registry: for a control held
    ``hold`` plan knots, at ``target_speed`` [m/s] where the plan reads them, ``Task.plan_inputs``), save it to
    ``path`` and return its summary ([`hsddp_gym.rollout.plans.plan_summary`][hsddp_gym.rollout.plans.plan_summary])."""
    from hsddp_gym.rollout.plans import plan_summary, task_plan

    task = task_of_env_id(check_env_id(env_id))
    inputs = {k: {"hold": hold, "speed": target_speed}[k] for k in task.plan_inputs}
    task_plan(task, **inputs).save(path)
    return plan_summary(task, **inputs)


# ================================================================================================ episodes
@dataclasses.dataclass
class Episode:
    """One recorded episode (Minari layout): ``observations (T+1, d)``, ``actions (T, 4)``, ``rewards (T,)``,
    ``terminations (T,)``, ``truncations (T,)``, ``infos`` {key: (T+1, ...)}."""

    index: int
    seed: int
    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray
    infos: dict
    wall_time: float = 0.0

    @property
    def length(self) -> int:
        return int(len(self.actions))

    @property
    def episode_return(self) -> float:
        return float(np.sum(self.rewards))


_CAPTURE: dict = {}


@contextlib.contextmanager
def capture_plan_controls():
    """While active, every
    [`PlanTracker.control`][hsddp_gym.planners.policies.tracking.PlanTracker.control] call records the knot it used in
    the returned dict (``"X"``, ``"U"``, ``"K"`` of that knot) and the torques (4,) [N m] its law gave (``"u"``).

    The trackers of [`PlanTrackingPolicy`][hsddp_gym.planners.policies.tracking_policy.PlanTrackingPolicy] and
    [`MPCPolicy`][hsddp_gym.planners.policies.mpc.agent.MPCPolicy]
    advance their cursor right after computing the control, so the knot cannot be read afterwards; this
    wraps the method (class level, restored on exit) for the duration of one episode in this process.
    """
    from hsddp_gym.planners.policies.tracking import PlanTracker

    original = PlanTracker.control
    slot: dict = {}

    def control(self, x):
        k = self.knot
        slot["X"], slot["U"], slot["K"] = self.X[k], self.U[k], self.K[k]
        slot["u"] = original(self, x)
        return slot["u"]

    PlanTracker.control = control
    try:
        yield slot
    finally:
        PlanTracker.control = original


def _max_violation(sol) -> float:
    vals = [float(np.max(np.abs(sol.switching))) if np.size(sol.switching) else 0.0]
    if sol.log:
        rec = sol.log[-1]
        vals += [rec.max_torque_violation, rec.max_friction_violation, -rec.min_normal_grf]
    vals = [v for v in vals if np.isfinite(v)]
    return float(max([0.0, *vals]))


class DecisionRecorder:
    """Builds the policy-decision ``infos`` ([`DECISION_SCHEMA`][DECISION_SCHEMA]) around ``policy(obs)`` calls."""

    def __init__(self, policy, torque_limit: float, include_gains: bool = False) -> None:
        self.policy = policy
        self.torque_limit = float(torque_limit)
        self.include_gains = include_gains
        self.last = {k: np.zeros(shape, dtype=dtype) for k, (shape, dtype) in DECISION_SCHEMA.items()}
        if include_gains:
            self.last[GAIN_KEY] = np.zeros((NU, NX))
        sol = getattr(policy, "solution", None)
        if sol is not None and hasattr(sol, "ddp_iterations"):  # a plan solved offline (the expert)
            self.last["solver_iterations"] = np.array(int(sol.ddp_iterations))
            self.last["solver_converged"] = np.array(bool(sol.converged))
            self.last["max_violation"] = np.array(_max_violation(sol))
            self.last["solve_ms"] = np.array(1e3 * float(sol.solve_time))

    def act(self, obs, slot: dict) -> tuple[np.ndarray, dict]:
        """``(action (4,) float32, decision info)`` for one observation."""
        stats = getattr(self.policy, "stats", None)
        planner = isinstance(stats, dict) and "solve_ms" in stats and "replans" in stats
        n_solves = len(stats["solve_ms"]) if planner else 0
        n_ok = stats["replans"] if planner else 0
        slot.clear()
        action = np.asarray(self.policy(obs), dtype=np.float32)
        d = {k: v.copy() for k, v in self.last.items()}
        d["replanned"] = np.array(False)
        d["planner_failed"] = np.array(False)
        # the law produced the action unless the policy changed its torques afterwards (the MPC's projection of
        # stance torques that would push a foot off the ground)
        law = np.clip(np.asarray(slot["u"], dtype=np.float64) / self.torque_limit, -1.0, 1.0) if "u" in slot else None
        d["expert_tracking"] = np.array(law is not None and bool(np.allclose(action, law, rtol=0.0, atol=1e-6)))
        if "U" in slot:
            d["expert_state_nominal"] = np.array(slot["X"], dtype=np.float64)
            d["expert_action_nominal"] = np.array(slot["U"], dtype=np.float64) / self.torque_limit
            if self.include_gains:
                K = np.array(slot["K"], dtype=np.float64) / self.torque_limit
                K[:, 0] = 0.0
                d[GAIN_KEY] = K
        if planner and len(stats["solve_ms"]) > n_solves:
            d["replanned"] = np.array(True)
            d["solve_ms"] = np.array(float(stats["solve_ms"][-1]))
            if stats["replans"] > n_ok:
                sol = self.policy.last_solution
                d["solver_iterations"] = np.array(int(stats["iterations"][-1]))
                d["solver_converged"] = np.array(bool(getattr(sol, "converged", False)))
                d["max_violation"] = np.array(_max_violation(sol) if sol is not None else 0.0)
            else:
                d["planner_failed"] = np.array(True)
                d["solver_iterations"] = np.array(0)
                d["solver_converged"] = np.array(False)
        self.last = d
        return action, d

    def final(self) -> dict:
        """The last row's decision values (no action at the final observation)."""
        d = {k: v.copy() for k, v in self.last.items()}
        d["replanned"] = np.array(False)
        d["planner_failed"] = np.array(False)
        return d


def inform_sent_action(policy, action) -> None:
    """Tell a policy that remembers the actions it returned which action was actually sent to the env in its
    place (the learner's in a DAgger rollout, or the expert's plus DART noise), through its public
    ``note_sent_action(action)`` when it has one
    ([`note_sent_action`][hsddp_gym.planners.policies.mpc.agent.MPCPolicy.note_sent_action]: the MPC feeds its last
    returned actions to its state filter and latency compensation, which would otherwise predict with an action the env
    never executed). Other policies are left alone.
    """
    note = getattr(policy, "note_sent_action", None)
    if callable(note):
        note(action)


def _info_schema(info: dict) -> dict:
    return {k: (np.asarray(v).shape, np.asarray(v).dtype) for k, v in info.items()}


def _check_info(info: dict, schema: dict, step: int) -> None:
    if set(info) != set(schema):
        raise ValueError(f"env info keys changed at step {step}: expected {sorted(schema)}, got {sorted(info)}")
    for k, (shape, _) in schema.items():
        if np.asarray(info[k]).shape != shape:
            raise ValueError(f"env info[{k!r}] changed shape at step {step}: {shape} -> {np.asarray(info[k]).shape}")


class _RecordingPolicy:
    """What the episode loop plays while recording: the policy through its [`DecisionRecorder`][DecisionRecorder] (on
    the true state with ``privileged``), with DART noise on the sent action."""

    def __init__(self, policy, env, slot: dict, include_gains: bool, noise_rng, action_noise: float,
                 privileged: bool) -> None:
        self.policy, self.env, self.slot, self.include_gains = policy, env, slot, include_gains
        self.noise_rng, self.action_noise, self.privileged = noise_rng, action_noise, privileged
        self.reset_options = getattr(policy, "reset_options", None)
        self.rec, self.decision = None, None

    def reset(self) -> None:
        if hasattr(self.policy, "reset"):
            self.policy.reset()
        torque_limit = float(getattr(self.env.unwrapped, "torque_limit", 1.0))
        self.rec = DecisionRecorder(self.policy, torque_limit, self.include_gains)

    def __call__(self, obs) -> np.ndarray:
        from hsddp_gym.envs.perturbations import true_observation

        action, decision = self.rec.act(true_observation(self.env) if self.privileged else obs, self.slot)
        if self.noise_rng is not None:
            decision = {**decision, "expert_action": action.copy()}
            action = np.clip(action + self.action_noise * self.noise_rng.standard_normal(action.shape), -1.0,
                             1.0).astype(np.float32)
            if self.privileged:
                inform_sent_action(self.policy, action)
        self.decision = decision
        return action


class _EpisodeRows:
    """Observer of the recorded episode: the observations, actions, rewards, flags and ``infos`` rows (the env's
    ``info`` without the wrappers' keys, and the decision behind each action)."""

    def __init__(self, actor: _RecordingPolicy, drop) -> None:
        self.actor, self.drop = actor, drop

    def _env_info(self, info: dict) -> dict:
        return {k: v for k, v in info.items() if k not in self.drop} if self.drop else info

    def on_reset(self, env, obs, info) -> None:
        self.info = self._env_info(info)
        self.schema = _info_schema(self.info)
        self.observations, self.actions, self.rewards, self.terms, self.truncs, self.rows = [obs], [], [], [], [], []

    def on_step(self, env, action, obs, reward, terminated, truncated, info) -> None:
        self.rows.append({**self.info, **self.actor.decision})
        self.info = self._env_info(info)
        _check_info(self.info, self.schema, len(self.actions))
        self.observations.append(obs)
        self.actions.append(action)
        self.rewards.append(float(reward))
        self.terms.append(bool(terminated))
        self.truncs.append(bool(truncated))


def record_episode(env, policy, seed: int, options: dict | None = None, index: int = 0,
                   include_gains: bool = False, action_noise: float = 0.0, privileged: bool = False) -> Episode:
    """Play one episode of ``env`` with ``policy`` from ``env.reset(seed=seed, options=options)`` (the policy's
    ``reset_options`` added, [`hsddp_gym.rollout.episodes.run_episode`][hsddp_gym.rollout.episodes.run_episode]).

    ``policy`` is any callable ``obs -> action`` with an optional ``reset()``; planner statistics and the
    tracked plan knot are recorded when it has them (see the module docstring).

    ``action_noise > 0`` (DART noise injection): the executed (and recorded) action is
    ``clip(a + action_noise * N(0, I), -1, 1)`` with ``a`` the policy's action, the noise drawn from
    ``np.random.default_rng([NOISE_STREAM, seed])``; ``a`` itself is stored in ``infos["expert_action"]``
    (row t: the clean action at observation t; the last row repeats the last one) -- the label for imitation.

    ``privileged=True`` (demonstrations under a perturbation, ``hsddp-gym dataset --condition``): the policy
    acts on [`hsddp_gym.envs.perturbations.true_observation`][hsddp_gym.envs.perturbations.wrappers.true_observation]
    (the true state; it differs from the env's observation only under
    [`ObservationNoise`][hsddp_gym.envs.perturbations.wrappers.ObservationNoise]) while ``observations`` keep the env's
    (perturbed) ones -- the learner's input: the label is the expert's action at the true state of the learner's
    situation; with DART noise the policy is also told the noisy action that was sent
    ([`inform_sent_action`][inform_sent_action]; without ``privileged`` it is not, as before, so older datasets
    reproduce). The keys wrappers add to ``info`` (``push``, ``executed_action``:
    [`wrapper_info_keys`][hsddp_gym.envs.perturbations.wrappers.wrapper_info_keys]) are not recorded, so the schema
    stays the env's. """
    from hsddp_gym.envs.perturbations import wrapper_info_keys
    from hsddp_gym.rollout.episodes import run_episode

    action_noise = check_positive(action_noise, "action_noise", allow_zero=True)
    if not isinstance(privileged, (bool, np.bool_)):
        raise TypeError(f"privileged must be a bool, got {type(privileged).__name__}")
    noise_rng = np.random.default_rng([NOISE_STREAM, int(seed)]) if action_noise > 0 else None
    t0 = time.perf_counter()
    with capture_plan_controls() as slot:
        actor = _RecordingPolicy(policy, env, slot, include_gains, noise_rng, action_noise, privileged)
        rows = _EpisodeRows(actor, wrapper_info_keys(env))
        run_episode(env, actor, seed, options=options, observers=(rows,))
    final = actor.rec.final()
    if noise_rng is not None:
        final["expert_action"] = rows.rows[-1]["expert_action"].copy()
    rows.rows.append({**rows.info, **final})
    infos = {k: np.stack([np.asarray(r[k]) for r in rows.rows]) for k in rows.rows[0]}
    if noise_rng is not None:
        infos["expert_action"] = infos["expert_action"].astype(np.float32)
    for k, (shape, dtype) in DECISION_SCHEMA.items():
        infos[k] = infos[k].astype(dtype, copy=False).reshape(len(rows.rows), *shape)
    return Episode(index=int(index), seed=int(seed), observations=np.asarray(rows.observations, dtype=np.float32),
                   actions=np.asarray(rows.actions, dtype=np.float32),
                   rewards=np.asarray(rows.rewards, dtype=np.float64), terminations=np.asarray(rows.terms, dtype=bool),
                   truncations=np.asarray(rows.truncs, dtype=bool), infos=infos, wall_time=time.perf_counter() - t0)
