"""Recording one episode: the policies by name, the expert's plan, per-step decisions (the dataset schema)."""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import time

import numpy as np

from hsddp_gym.core.conventions import NU, NX
from hsddp_gym.util.validation import check_positive

ENV_ID = "hsddp_gym/Bounding-v0"
PRONKING_ENV_ID = "hsddp_gym/Pronking-v0"
BACKFLIP_ENV_ID = "hsddp_gym/Backflip-v0"
JUMP_ENV_IDS = {"hsddp_gym/GapJump-v0": "gap_jump", "hsddp_gym/BoxJump-v0": "box_jump"}
"""The jump tasks' envs and their motions (``hsddp_gym.planners.motions.JUMPS``)."""
TRANSITION_ENV_IDS = {"hsddp_gym/StandToBound-v0": "stand_to_bound",
                      "hsddp_gym/BoundPronkBound-v0": "bound_pronk_bound", "hsddp_gym/BoundToStop-v0": "bound_to_stop"}
"""The gait-transition tasks' envs and their tasks (``hsddp_gym.planners.motions.TRANSITIONS``)."""
TERRAIN_ENV_ID = "hsddp_gym/Terrain-v0"
"""Bounding-v0 on a seeded random terrain per episode: its ``mpc`` is the terrain-aware MPC (:data:`MPC_ENVS`)."""
DATASET_ENVS = (ENV_ID, PRONKING_ENV_ID, BACKFLIP_ENV_ID, *JUMP_ENV_IDS, TERRAIN_ENV_ID, *TRANSITION_ENV_IDS)
"""The envs datasets are recorded in (``generate_dataset(env_id=...)``, ``hsddp-gym dataset --env``)."""
MPC_ENVS = (ENV_ID, TERRAIN_ENV_ID)
"""The envs whose expert is the MPC (``mpc``; the others' is their task's plan tracker, ``expert``). In
``hsddp_gym/Terrain-v0`` the MPC is given each episode's terrain: ``MPCPolicy(EnvInterface.from_env(env),
options, terrain=env_terrain(env))`` (:func:`hsddp_gym.planners.policies.mpc.env_terrain`, read at every reset)."""
POLICIES = ("mpc", "expert", "heuristic", "random")
EXPERT_PLAN = {"method": "al-reb", "cycles": 5}
"""The expert's plan: ``hsddp_gym.planners.tasks.plan_bounding("al-reb", cycles=5)`` (paper task 1, 1 m/s)."""
EXPERT_PRONK_PLAN = {"motion": "pronk", "cycles": 4}
"""The pronking expert's plan in Pronking-v0: ``hsddp_gym.planners.motions.plan_pronk(4, target_speed)``, tracked
periodically (:func:`hsddp_gym.planners.policies.experts.pronking_expert`)."""
EXPERT_BACKFLIP_PLAN = {"motion": "backflip", "hold": "control period / 1 ms (5 by default)"}
"""The backflip expert's plan in Backflip-v0: ``hsddp_gym.planners.motions.plan_backflip_held(hold)``, tracked then
held (:func:`hsddp_gym.planners.policies.experts.backflip_expert`)."""
EXPERT_JUMP_PLAN = {"motion": "gap_jump or box_jump", "speed": 1.0, "cycles": 2,
                    "hold": "control period / 1 ms (5 by default)"}
"""The jump expert's plan in GapJump-v0 / BoxJump-v0: ``hsddp_gym.planners.motions.plan_jump_held(motion, hold)``,
tracked, then its cycle after the jump looped (:func:`hsddp_gym.planners.policies.experts.jump_expert`)."""
EXPERT_TRANSITION_PLAN = {"motion": "stand_to_bound, bound_pronk_bound or bound_to_stop", "speed": 1.0,
                          "cycles": "hsddp_gym.planners.policies.experts.TRANSITION_PLAN_CYCLES[motion]",
                          "hold": "control period / 1 ms (5 by default)"}
"""The transition expert's plan in StandToBound-v0 / BoundPronkBound-v0 / BoundToStop-v0:
``hsddp_gym.planners.motions.plan_transition_held(motion, hold, cycles=TRANSITION_PLAN_CYCLES[motion])``, tracked,
then its bounding cycle looped or its last posture held
(:func:`hsddp_gym.planners.policies.experts.transition_expert`)."""
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
    """``env_id`` (None: :data:`ENV_ID`) if it is one of :data:`DATASET_ENVS`, else ``ValueError`` naming it."""
    if env_id is None:
        return ENV_ID
    if env_id not in DATASET_ENVS:
        raise ValueError(f"env_id must be one of {DATASET_ENVS}, got {env_id!r}")
    return str(env_id)


# ================================================================================================ policies
@dataclasses.dataclass(frozen=True)
class PolicySpec:
    """A picklable recipe for the policy of one episode (the default ``policy_factory``).

    Args:
        name: one of :data:`POLICIES`.
        options: ``MPCOptions`` fields for ``mpc`` (JSON-serializable values); unused otherwise.
        plan_path: the expert's plan (``.npz`` of :meth:`hsddp_gym.planners.optimizer.solution.Solution.save`);
            ``expert`` only.
        env_id: the env the expert's plan is for (None: Bounding-v0, the bounding expert): in
            ``hsddp_gym/Pronking-v0`` the expert is :func:`~hsddp_gym.planners.policies.experts.pronking_expert` of a
            pronk plan, in ``hsddp_gym/Backflip-v0`` :func:`~hsddp_gym.planners.policies.experts.backflip_expert` of
            a backflip plan (no reset options), in the jumps' and the gait transitions' envs their task's expert
            (:func:`~hsddp_gym.planners.policies.experts.jump_expert`,
            :func:`~hsddp_gym.planners.policies.experts.transition_expert`); in ``hsddp_gym/Terrain-v0``
            ``mpc`` is the terrain-aware MPC (the episode's terrain as privileged information, :data:`MPC_ENVS`).
    """

    name: str
    options: dict = dataclasses.field(default_factory=dict)
    plan_path: str | None = None
    env_id: str | None = None

    def __post_init__(self) -> None:
        if self.name not in POLICIES:
            raise ValueError(f"policy name must be one of {POLICIES}, got {self.name!r}")
        if self.name == "expert" and self.plan_path is None:
            raise ValueError("the expert policy needs plan_path (its plan, saved with Solution.save)")
        if self.name == "expert" and check_env_id(self.env_id) == TERRAIN_ENV_ID:
            raise ValueError(f"in {TERRAIN_ENV_ID} the expert is 'mpc' (the terrain-aware MPC), not a plan tracker")
        check_env_id(self.env_id)

    def __call__(self, env, episode_seed: int):
        """``(policy, reset_options)`` for an episode of ``env`` seeded ``episode_seed``."""
        from hsddp_gym.planners.policies import experts
        from hsddp_gym.planners.policies.base import EnvInterface
        from hsddp_gym.planners.policies.heuristic import HeuristicPolicy
        from hsddp_gym.planners.policies.random_policy import RandomPolicy

        if self.name == "mpc":
            from hsddp_gym.planners.policies.mpc import MPCOptions, MPCPolicy, env_terrain

            terrain = env_terrain(env) if check_env_id(self.env_id) == TERRAIN_ENV_ID else None
            return MPCPolicy.from_env(env, options=MPCOptions(**_mpc_options(self.options)), terrain=terrain), None
        if self.name == "expert":
            interface, sol = EnvInterface.from_env(env), _load_plan(str(self.plan_path))
            env_id = check_env_id(self.env_id)
            if env_id == PRONKING_ENV_ID:
                return experts.pronking_expert(interface, sol), None
            if env_id == BACKFLIP_ENV_ID:
                return experts.backflip_expert(interface, sol), None
            if env_id in JUMP_ENV_IDS:
                return experts.jump_expert(interface, sol), None
            if env_id in TRANSITION_ENV_IDS:
                return experts.transition_expert(interface, sol, TRANSITION_ENV_IDS[env_id]), None
            return experts.bounding_expert(interface, sol), {"state": sol.X[0].copy()}
        if self.name == "heuristic":
            return HeuristicPolicy.from_env(env), None
        return RandomPolicy.from_env(env, seed=int(episode_seed)), None

    def describe(self) -> dict:
        """JSON description (name and the full options in effect)."""
        policies = "hsddp_gym.planners.policies"
        d = {"name": self.name, "class": {"mpc": f"{policies}.mpc.MPCPolicy",
                                          "expert": f"{policies}.tracking_policy.PlanTrackingPolicy",
                                          "heuristic": f"{policies}.heuristic.HeuristicPolicy",
                                          "random": f"{policies}.random_policy.RandomPolicy"}[self.name]}
        if self.name == "mpc":
            from hsddp_gym.planners.policies.mpc import MPCOptions

            d["options"] = dataclasses.asdict(MPCOptions(**_mpc_options(self.options)))
            if check_env_id(self.env_id) == TERRAIN_ENV_ID:
                d["terrain"] = ("env_terrain(env): the episode's terrain (privileged information), read at every "
                                "reset")
        elif self.name == "expert" and check_env_id(self.env_id) == PRONKING_ENV_ID:
            d["configuration"] = f"{policies}.experts.pronking_expert"
            d["options"] = {"plan": dict(EXPERT_PRONK_PLAN), "plan_file": "expert_plan.npz",
                            "tracking": "periodic: after the plan's last touchdown the cursor returns to phase 2",
                            "reset_options": "none (the env starts at the plan's start, with reset noise)"}
        elif self.name == "expert" and check_env_id(self.env_id) == BACKFLIP_ENV_ID:
            d["configuration"] = f"{policies}.experts.backflip_expert"
            d["options"] = {"plan": dict(EXPERT_BACKFLIP_PLAN), "plan_file": "expert_plan.npz",
                            "tracking": "the plan's held-input feedback law, touchdowns counted for feet seen 2 cm "
                                        "clear; after the plan a joint PD on its last posture",
                            "reset_options": "none (the env starts at the plan's start, with reset noise)"}
        elif self.name == "expert" and check_env_id(self.env_id) in JUMP_ENV_IDS:
            d["configuration"] = f"{policies}.experts.jump_expert"
            d["options"] = {"plan": {**EXPERT_JUMP_PLAN, "motion": JUMP_ENV_IDS[self.env_id]},
                            "plan_file": "expert_plan.npz",
                            "tracking": "the plan's held-input feedback law, touchdowns counted for feet seen 2 cm "
                                        "clear; after the plan its first cycle after the jump, looped",
                            "reset_options": "none (the env starts at the plan's start, with reset noise)"}
        elif self.name == "expert" and check_env_id(self.env_id) in TRANSITION_ENV_IDS:
            from hsddp_gym.planners.policies.experts import TRANSITION_LOOPS, TRANSITION_PLAN_CYCLES

            task = TRANSITION_ENV_IDS[self.env_id]
            loop = TRANSITION_LOOPS[task]
            after = ("its last control plus a joint PD to its last knot's joint angles" if loop[0] is None
                     else f"its bounding cycle (phases {loop[0]}-{loop[1] - 1}), looped")
            d["configuration"] = f"{policies}.experts.transition_expert"
            d["options"] = {"plan": {**EXPERT_TRANSITION_PLAN, "motion": task, "cycles": TRANSITION_PLAN_CYCLES[task]},
                            "plan_file": "expert_plan.npz",
                            "tracking": "the plan's held-input feedback law, touchdowns counted for feet seen clear "
                                        "(2 cm, or half the plan's lowest landing-foot peak if lower); after the plan "
                                        + after,
                            "reset_options": "none (the env starts at the plan's start, with reset noise)"}
        elif self.name == "expert":
            d["configuration"] = f"{policies}.experts.bounding_expert"
            d["options"] = {"plan": dict(EXPERT_PLAN), "plan_file": "expert_plan.npz",
                            "reset_options": "{'state': plan.X[0]} (no reset noise)",
                            "fallback_after_plan": "hsddp_gym.planners.policies.mpc.MPCPolicy (default options)"}
        elif self.name == "random":
            d["options"] = {"seed": "episode seed"}
        else:
            d["options"] = {}
        return d


def _mpc_options(options: dict) -> dict:
    opts = dict(options)
    if opts.get("durations") is not None:
        opts["durations"] = tuple(opts["durations"])
    return opts


@functools.lru_cache(maxsize=4)
def _load_plan(path: str):
    from hsddp_gym.planners.optimizer.solution import Solution

    return Solution.load(path)


def solve_expert_plan(path, env_id: str | None = None, target_speed: float = 1.0, hold: int = 5) -> dict:
    """Solve the expert's plan (:data:`EXPERT_PLAN`; in Pronking-v0 :data:`EXPERT_PRONK_PLAN` at ``target_speed``
    [m/s]; in Backflip-v0 :data:`EXPERT_BACKFLIP_PLAN`, in GapJump-v0 / BoxJump-v0 :data:`EXPERT_JUMP_PLAN`, in the
    gait transitions' envs :data:`EXPERT_TRANSITION_PLAN`, for a control held ``hold`` plan knots), save it to
    ``path``
    and return its summary."""
    if check_env_id(env_id) in (BACKFLIP_ENV_ID, *JUMP_ENV_IDS, *TRANSITION_ENV_IDS):
        from hsddp_gym.planners.motions import plan_backflip_held, plan_jump_held, plan_transition_held
        from hsddp_gym.planners.policies.experts import TRANSITION_PLAN_CYCLES

        if env_id == BACKFLIP_ENV_ID:
            sol = plan_backflip_held(hold)
        elif env_id in JUMP_ENV_IDS:
            sol = plan_jump_held(JUMP_ENV_IDS[env_id], hold)
        else:
            task = TRANSITION_ENV_IDS[env_id]
            sol = plan_transition_held(task, hold, cycles=TRANSITION_PLAN_CYCLES[task])
        sol.save(path)
        return {"status": sol.status, "converged": bool(sol.converged), "al_iterations": int(sol.al_iterations),
                "ddp_iterations": int(sol.ddp_iterations), "switching_violation": float(sol.switching_violation),
                "cost": float(sol.cost), "solve_time_s": float(sol.solve_time), "hold": int(hold)}
    if check_env_id(env_id) == PRONKING_ENV_ID:
        from hsddp_gym.planners.motions import plan_pronk

        result = plan_pronk(EXPERT_PRONK_PLAN["cycles"], float(target_speed))
    else:
        from hsddp_gym.planners.tasks import plan_bounding

        result = plan_bounding(EXPERT_PLAN["method"], cycles=EXPERT_PLAN["cycles"])
    result.solution.save(path)
    keep = ("status", "converged", "al_iterations", "ddp_iterations", "switching_violation", "cost",
            "avg_forward_speed", "solve_time_s")
    return {k: result.summary[k] for k in keep if k in result.summary}


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
    """While active, every :meth:`hsddp_gym.planners.policies.tracking.PlanTracker.control` call records the knot it
    used in the returned dict (``"X"``, ``"U"``, ``"K"`` of that knot) and the torques (4,) [N m] its law gave
    (``"u"``).

    The trackers of :class:`~hsddp_gym.planners.policies.tracking_policy.PlanTrackingPolicy` and
    :class:`~hsddp_gym.planners.policies.mpc.MPCPolicy`
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
    """Builds the policy-decision ``infos`` (:data:`DECISION_SCHEMA`) around ``policy(obs)`` calls."""

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
    (:meth:`~hsddp_gym.planners.policies.mpc.MPCPolicy.note_sent_action`: the MPC feeds its last returned actions to
    its state filter and latency compensation, which would otherwise predict with an action the env never
    executed). Other policies are left alone.
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


def record_episode(env, policy, seed: int, options: dict | None = None, index: int = 0,
                   include_gains: bool = False, action_noise: float = 0.0, privileged: bool = False) -> Episode:
    """Play one episode of ``env`` with ``policy`` from ``env.reset(seed=seed, options=options)``.

    ``policy`` is any callable ``obs -> action`` with an optional ``reset()``; planner statistics and the
    tracked plan knot are recorded when it has them (see the module docstring).

    ``action_noise > 0`` (DART noise injection): the executed (and recorded) action is
    ``clip(a + action_noise * N(0, I), -1, 1)`` with ``a`` the policy's action, the noise drawn from
    ``np.random.default_rng([NOISE_STREAM, seed])``; ``a`` itself is stored in ``infos["expert_action"]``
    (row t: the clean action at observation t; the last row repeats the last one) -- the label for imitation.

    ``privileged=True`` (demonstrations under a perturbation, ``hsddp-gym dataset --condition``): the policy
    acts on :func:`hsddp_gym.envs.perturbations.true_observation` (the true state; it differs from the env's
    observation only under :class:`~hsddp_gym.envs.perturbations.ObservationNoise`) while ``observations``
    keep the env's (perturbed) ones -- the learner's input: the label is the expert's action at the true state
    of the learner's situation; with DART noise the policy is also told the noisy action that was sent
    (:func:`inform_sent_action`; without ``privileged`` it is not, as before, so older datasets reproduce).
    The keys wrappers add to ``info`` (``push``, ``executed_action``:
    :func:`~hsddp_gym.envs.perturbations.wrapper_info_keys`) are not recorded, so the schema stays the env's.
    """
    from hsddp_gym.envs.perturbations import true_observation, wrapper_info_keys

    action_noise = check_positive(action_noise, "action_noise", allow_zero=True)
    if not isinstance(privileged, (bool, np.bool_)):
        raise TypeError(f"privileged must be a bool, got {type(privileged).__name__}")
    drop = wrapper_info_keys(env)

    def env_info(i: dict) -> dict:
        return {k: v for k, v in i.items() if k not in drop} if drop else i

    noise_rng = np.random.default_rng([NOISE_STREAM, int(seed)]) if action_noise > 0 else None
    t0 = time.perf_counter()
    obs, info = env.reset(seed=int(seed), options=options)
    info = env_info(info)
    if hasattr(policy, "reset"):
        policy.reset()
    schema = _info_schema(info)
    torque_limit = float(getattr(env.unwrapped, "torque_limit", 1.0))
    rec = DecisionRecorder(policy, torque_limit, include_gains)
    observations, actions, rewards, terms, truncs, rows = [obs], [], [], [], [], []
    with capture_plan_controls() as slot:
        while True:
            action, decision = rec.act(true_observation(env) if privileged else obs, slot)
            if noise_rng is not None:
                decision = {**decision, "expert_action": action.copy()}
                action = np.clip(action + action_noise * noise_rng.standard_normal(action.shape), -1.0,
                                 1.0).astype(np.float32)
                if privileged:
                    inform_sent_action(policy, action)
            rows.append({**info, **decision})
            obs, reward, terminated, truncated, info = env.step(action)
            info = env_info(info)
            _check_info(info, schema, len(actions))
            observations.append(obs)
            actions.append(action)
            rewards.append(float(reward))
            terms.append(bool(terminated))
            truncs.append(bool(truncated))
            if terminated or truncated:
                break
    final = rec.final()
    if noise_rng is not None:
        final["expert_action"] = rows[-1]["expert_action"].copy()
    rows.append({**info, **final})
    infos = {k: np.stack([np.asarray(r[k]) for r in rows]) for k in rows[0]}
    if noise_rng is not None:
        infos["expert_action"] = infos["expert_action"].astype(np.float32)
    for k, (shape, dtype) in DECISION_SCHEMA.items():
        infos[k] = infos[k].astype(dtype, copy=False).reshape(len(rows), *shape)
    return Episode(index=int(index), seed=int(seed), observations=np.asarray(observations, dtype=np.float32),
                   actions=np.asarray(actions, dtype=np.float32), rewards=np.asarray(rewards, dtype=np.float64),
                   terminations=np.asarray(terms, dtype=bool), truncations=np.asarray(truncs, dtype=bool),
                   infos=infos, wall_time=time.perf_counter() - t0)
