"""DAgger (Ross et al. 2011) with an expert that runs alongside the learner; see
[`hsddp_gym.learning`][hsddp_gym.learning]."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from hsddp_gym.learning.bc import BCConfig, MLPPolicy, train_bc
from hsddp_gym.learning.demonstrations import Demonstrations, load_demonstrations
from hsddp_gym.learning.features import make_gait_clock
from hsddp_gym.learning.reporting import eval_brief, evaluate_policy_episodes, plot_curve, write_csv
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.util.io import write_npz

# ================================================================================================ DAgger
KEEP = ("last", "best")
"""The learners a DAgger run can return (``DAggerConfig.keep``)."""


def round_rank(evaluation: dict) -> tuple:
    """The key a ``keep="best"`` run minimizes over its rounds' evaluations
    (``eval_brief`` of [`hsddp_gym.learning.reporting`][hsddp_gym.learning.reporting]): falls, then minus the mean
    return."""
    return (int(evaluation["falls"]), -float(evaluation["mean_return"]))


@dataclasses.dataclass(frozen=True)
class DAggerConfig:
    """DAgger settings.

    Attributes:
        rounds: relabelling rounds after round 0. episodes_per_round: learner/mixture episodes per round
            (and expert episodes of round 0 when no initial demonstrations are given).
        beta_decay: ``beta_i = beta_decay ** i`` (round 0: 1, pure expert). 0 gives pure learner rollouts.
        bc: the BC settings used in every round (retrained from scratch on the aggregate data).
        seed: episode ``j`` of round ``i`` is reset with seed ``seed + 1000 * i + j``; the mixture draws come
            from ``np.random.default_rng([seed, i, j])``.
        max_episode_steps: time-limit override of the rollouts (None: the env's 1000).
        rollout_noise: DART-style noise in rounds >= 1: the executed action (expert's or learner's) gets
            i.i.d. Gaussian noise of this std (normalized units, clipped to [-1, 1]) drawn from the round's
            generator, so the aggregate data covers the recoveries from perturbed states; the label stays the
            expert's clean action (0: none).
        warm_start: rounds >= 1 start training from the previous round's network and input standardization
            (``epochs`` per round, lr schedule restarted) instead of a fresh initialization.
        conditions: names of
            [`hsddp_gym.envs.perturbations.CONDITIONS`][hsddp_gym.envs.perturbations.conditions.CONDITIONS] (empty: the
            plain env; in a task's env, the conditions that apply to the task, built for it: its push window and
            sizes): episode ``j`` of every round runs in ``conditions[j % len(conditions)]`` (its perturbation seeded by
            its episode seed), so the learner is relabelled in the perturbed states it reaches. The expert
            runs alongside on the *true* state
            ([`hsddp_gym.envs.perturbations.true_observation`][hsddp_gym.envs.perturbations.wrappers.true_observation]:
            without the observation noise) and is told the action actually sent
            ([`hsddp_gym.datasets.recording.inform_sent_action`][hsddp_gym.datasets.recording.inform_sent_action]), so
            under latency its prediction of the pending actions holds the learner's; the learner acts on (and the labels
            are stored with) the perturbed observation.
        rollout_steps: truncate the relabelling rollouts of rounds >= 1 after this many steps (None: run to
            the end of the episode). The learner's falls happen in the first ~150 steps (the start transient
            from the reset noise), so short rollouts spend the label budget on many initial states instead of
            on steady bounding. Only the labelled steps count; the evaluation is not truncated.
        estimator: the learner acts behind the MPC's perception
            ([`EstimatedStatePolicy`][hsddp_gym.planners.policies.estimated_state.EstimatedStatePolicy]: the state
            filter, the prediction over the action delay): every rollout stores what the learner sees through it (the
            estimate, predicted over the delay; the expert's label is its action for the true state, its own prediction
            over the delay included: the action for that predicted state), and the trained learner is meant to act
            behind it. Round-0 demonstrations (``initial``) are used as they are: give ones of undisturbed envs, where
            the estimate is the observation. Excludes ``bc.action_queue`` (the prediction replaces the queue).
        env_id: the env of the rollouts, the learner's interface and the evaluations, one of
            [`hsddp_gym.datasets.recording.DATASET_ENVS`][hsddp_gym.datasets.recording.DATASET_ENVS] (None:
            Bounding-v0). A task's env takes no ``estimator`` (it is Bounding-v0's); the pronk's expert is its plan
            tracker
            ([`pronking_expert`][hsddp_gym.planners.policies.experts.pronking_expert], ``PolicySpec("expert",
            env_id=...)``).
        keep: which round's learner the result is: ``"last"`` (the last round's) or ``"best"`` (the round whose
            evaluation fell least, ties to the higher mean return; the first such round: DAgger's guarantee is for the
            best policy of the sequence, Ross et al. 2011). ``"best"`` needs the per-round evaluation
            (``train_dagger(evaluate=...)``); its seeds are the training side's, not a test's.
    """

    rounds: int = 4
    episodes_per_round: int = 5
    beta_decay: float = 0.5
    bc: BCConfig = BCConfig()
    seed: int = 0
    max_episode_steps: int | None = None
    rollout_noise: float = 0.0
    warm_start: bool = False
    rollout_steps: int | None = None
    conditions: tuple = ()
    estimator: bool = False
    env_id: str | None = None
    keep: str = "last"

    def __post_init__(self) -> None:
        from hsddp_gym.datasets.recording import ENV_ID, check_env_id

        if self.keep not in KEEP:
            raise ValueError(f"keep must be one of {KEEP}, got {self.keep!r}")

        if self.env_id is not None:
            object.__setattr__(self, "env_id", check_env_id(self.env_id))
        if self.env_id not in (None, ENV_ID) and self.estimator:
            raise ValueError(f"env_id {self.env_id!r} takes no estimator (it is {ENV_ID}'s), got "
                             f"estimator={self.estimator!r}")
        if self.conditions:
            from hsddp_gym.datasets.collection import check_task_conditions

            object.__setattr__(self, "conditions", check_task_conditions(self.conditions, self.env_id, "conditions"))
        elif not isinstance(self.conditions, (tuple, list)):
            raise ValueError(f"conditions must be a list of condition names, got {self.conditions!r}")
        else:
            object.__setattr__(self, "conditions", ())
        if not isinstance(self.estimator, (bool, np.bool_)):
            raise TypeError(f"estimator must be a bool, got {self.estimator!r}")
        if self.estimator and int(self.bc.action_queue):
            raise ValueError("estimator and bc.action_queue exclude each other: behind the estimator the learner sees "
                             "the state predicted over the delay, not the queue")
        if int(self.bc.gain_copies):
            raise ValueError("bc.gain_copies must be 0 for DAgger: its relabelled rounds have no feedback gains "
                             "(gain labels are a behaviour-cloning option)")
        if int(self.rounds) < 0:
            raise ValueError(f"rounds must be >= 0, got {self.rounds!r}")
        if int(self.episodes_per_round) < 1:
            raise ValueError(f"episodes_per_round must be >= 1, got {self.episodes_per_round!r}")
        if not 0.0 <= float(self.beta_decay) <= 1.0:
            raise ValueError(f"beta_decay must be in [0, 1], got {self.beta_decay!r}")
        if self.rollout_steps is not None and int(self.rollout_steps) < 1:
            raise ValueError(f"rollout_steps must be >= 1 or None, got {self.rollout_steps!r}")
        if not float(self.rollout_noise) >= 0.0:
            raise ValueError(f"rollout_noise must be >= 0, got {self.rollout_noise!r}")

    def beta(self, round_index: int) -> float:
        return 1.0 if round_index == 0 else float(self.beta_decay) ** int(round_index)


@dataclasses.dataclass
class DAggerResult:
    """``policy`` (the learner of round ``selected_round``: the last, or the best with ``keep="best"``), ``data``
    (aggregate labels), ``history`` (one dict per round: ``round, beta, episodes, new_labels, expert_labels,
    transitions, rollout_mean_return, expert_actions_fraction, final_loss, eval`` (if evaluated)), ``expert_labels``
    (total), ``wall_time_s`` and ``selected_round``."""

    policy: MLPPolicy
    data: Demonstrations
    history: list
    expert_labels: int
    wall_time_s: float
    selected_round: int = -1


class DAggerMixture:
    """What a relabelling rollout plays ([`dagger_rollout`][dagger_rollout]): at every step the expert labels the true
    state, the learner acts on what it sees, and the action sent is the expert's with probability ``beta`` (the
    learner's otherwise) plus Gaussian noise; keeps the seen observations, the labels and the sent actions."""

    def __init__(self, env, learner, expert, beta: float, rng: np.random.Generator, noise: float,
                 perception) -> None:
        self.env, self.learner, self.expert, self.beta, self.rng = env, learner, expert, beta, rng
        self.noise, self.perception = noise, perception
        self.reset_options = getattr(expert, "reset_options", None)
        self.O, self.A, self.S, self.n_expert = [], [], [], 0

    def reset(self) -> None:
        self.expert.reset()
        if self.learner is not None:
            self.learner.reset()
        if self.perception is not None:
            self.perception.reset()
        self.O, self.A, self.S, self.n_expert = [], [], [], 0

    def __call__(self, obs) -> np.ndarray:
        from hsddp_gym.datasets.recording import inform_sent_action
        from hsddp_gym.envs.perturbations.wrappers import true_observation

        label = np.asarray(self.expert(true_observation(self.env)), dtype=np.float32)
        seen = self.perception.observation_for_inner(obs) if self.perception is not None else obs
        self.O.append(np.asarray(seen, dtype=np.float32))
        self.A.append(label)
        own = np.asarray(self.learner(seen), dtype=np.float32) if self.learner is not None else None
        use_expert = self.learner is None or self.rng.random() < self.beta
        self.n_expert += int(use_expert)
        action = label if use_expert else own
        if self.noise > 0:
            action = np.clip(action + self.noise * self.rng.standard_normal(action.shape), -1.0,
                             1.0).astype(np.float32)
        inform_sent_action(self.expert, action)
        if self.learner is not None:
            inform_sent_action(self.learner, action)
        if self.perception is not None:
            self.perception.record_sent(action)
        self.S.append(action)
        return action


def dagger_rollout(env, learner, expert, beta: float, seed: int, rng: np.random.Generator,
                   options: dict | None = None, noise: float = 0.0, max_steps: int | None = None,
                   perception=None) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, int]:
    """One episode (stopped after ``max_steps`` steps if given) in which the expert labels every visited
    observation and the executed action is the expert's with probability ``beta`` (the learner's otherwise),
    plus Gaussian noise of std ``noise`` (clipped to [-1, 1]; the label stays clean). The expert acts on the true state
    ([`hsddp_gym.envs.perturbations.true_observation`][hsddp_gym.envs.perturbations.wrappers.true_observation]; the
    env's observation unless it is wrapped in observation noise) and is told the action sent
    ([`inform_sent_action`][hsddp_gym.datasets.recording.inform_sent_action]); the learner acts on the env's
    observation, which is what is stored. The learner acts at every step, so that its memory (gait clock, latency queue)
    follows the episode whichever policy's action is sent, and it is told the action sent too. ``perception``: an
    [`EstimatedStatePolicy`][hsddp_gym.planners.policies.estimated_state.EstimatedStatePolicy] through which the learner
    sees (``DAggerConfig.estimator``): the learner acts on, and the rollout stores, its `observation_for_inner`. The
    episode starts from ``options`` and the expert's ``reset_options``
    ([`hsddp_gym.rollout.episodes.run_episode`][hsddp_gym.rollout.episodes.run_episode]). Returns ``(obs (T, d), expert
    actions (T, 4), sent actions (T, 4), return, expert acts)``."""
    from hsddp_gym.rollout.episodes import Returns, run_episode

    mixture = DAggerMixture(env, learner, expert, beta, rng, noise, perception)
    ret = Returns()
    run_episode(env, mixture, seed, options=options, max_steps=max_steps, observers=(ret,))
    return (np.array(mixture.O), np.array(mixture.A), np.array(mixture.S, dtype=np.float32), ret.total,
            mixture.n_expert)


@dataclasses.dataclass(frozen=True)
class RolloutTask:
    """One relabelling rollout (picklable, for a worker process): round ``round_index``, episode ``j``."""

    round_index: int
    j: int
    expert_factory: Callable
    learner: MLPPolicy | None
    config: DAggerConfig
    env_kwargs: dict

    @property
    def seed(self) -> int:
        return int(self.config.seed) + 1000 * int(self.round_index) + int(self.j)

    @property
    def condition(self) -> str | None:
        c = self.config.conditions
        return c[self.j % len(c)] if c else None


def run_rollout_task(task: RolloutTask) -> tuple:
    """Worker entry point: a fresh env (the task's condition) and expert, one [`dagger_rollout`][dagger_rollout]; the
    learner acts with the env's interface (its target speed, its action delay). Returns ``(obs, labels, sent
    actions, return, expert acts, target speed, action delay)``."""
    from hsddp_gym.datasets.collection import make_env

    cfg, r = task.config, task.round_index
    env = make_env(task.env_kwargs, cfg.max_episode_steps, task.condition, env_id=cfg.env_id)
    try:
        interface = EnvInterface.from_env(env)
        perception = None
        if cfg.estimator:
            from hsddp_gym.planners.policies.estimated_state import EstimatedStatePolicy

            interface = EstimatedStatePolicy.undelayed(interface)
        learner = task.learner.with_interface(interface) if task.learner is not None else None
        if cfg.estimator:
            perception = EstimatedStatePolicy(learner if learner is not None else Policy(interface),
                                              EnvInterface.from_env(env))
        expert = task.expert_factory(env, task.seed)
        O, A, S, ret, ne = dagger_rollout(env, learner, expert, cfg.beta(r), task.seed,
                                          np.random.default_rng([cfg.seed, r, task.j]),
                                          noise=float(cfg.rollout_noise) if r > 0 else 0.0,
                                          max_steps=cfg.rollout_steps if r > 0 else None, perception=perception)
        delay = EnvInterface.from_env(env).action_delay_steps
        return O, A, S, ret, ne, float(env.unwrapped.target_speed), delay
    finally:
        env.close()


def train_dagger(expert_factory: Callable, config: DAggerConfig = DAggerConfig(),
                 initial: Demonstrations | None = None, env_kwargs: dict | None = None,
                 evaluate: Callable | None = None, progress: bool = True, clock=None,
                 workers: int = 1) -> DAggerResult:
    """DAgger with any expert (see the module docstring).

    Args:
        expert_factory: ``(env, episode_seed) -> expert Policy`` (its ``reset_options`` attribute, when it has one,
            starts the rollouts), e.g. [`hsddp_gym.rollout.policies.PolicySpec`][hsddp_gym.rollout.policies.PolicySpec];
            one expert is built per rollout.
        initial: round-0 demonstrations (None: ``episodes_per_round`` expert episodes are recorded).
        evaluate: optional ``policy -> dict`` called on each round's learner (stored in the history).
        clock: the gait clock of ``gait_clock`` features (default: the default MPC's,
            [`make_gait_clock`][make_gait_clock]).
        workers: processes running a round's rollouts
            ([`hsddp_gym.util.parallel.run_parallel`][hsddp_gym.util.parallel.run_parallel]; each
            rollout has its own env, expert and seeds, so the result does not depend on it).
    """
    from tqdm import tqdm

    from hsddp_gym.datasets.collection import check_condition_kwargs, make_env
    from hsddp_gym.util.parallel import run_parallel

    workers = int(workers)
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    check_condition_kwargs(config.conditions, env_kwargs)
    t0 = time.perf_counter()
    env = make_env(env_kwargs, config.max_episode_steps, env_id=config.env_id)
    interface = EnvInterface.from_env(env)
    history = []
    data = initial
    expert_labels = 0
    if config.keep == "best" and evaluate is None:
        raise ValueError("keep='best' needs evaluate (the per-round evaluation it chooses by)")
    bar = tqdm(total=config.rounds + 1, desc="DAgger rounds", unit="round", disable=not progress)
    learner = None
    best = None  # (rank, round, learner) of keep="best"
    for r in range(config.rounds + 1):
        beta = config.beta(r)
        new, returns, expert_acts, n_eps = None, [], 0, 0
        if r > 0 or data is None:
            parts = []
            tasks = [RolloutTask(r, j, expert_factory, learner if r > 0 else None, config, dict(env_kwargs or {}))
                     for j in range(config.episodes_per_round)]
            results = run_parallel(run_rollout_task, tasks, workers=min(workers, len(tasks)))
            for O, A, S, ret, ne, speed, delay in results:
                # one episode each (id 0): concat numbers them after the data's, contiguously
                parts.append(Demonstrations(O, A, np.zeros(len(O), dtype=np.int64),
                                            target_speed=np.full(len(O), speed), sent_actions=S,
                                            action_delay=np.full(len(O), delay, dtype=np.int64)))
                returns.append(ret)
                expert_acts += ne
            new = parts[0]
            for p in parts[1:]:
                new = new.concat(p)
            n_eps = len(parts)
            data = new if data is None else data.concat(new)
            expert_labels += len(new)
        else:
            expert_labels += len(data)  # the initial demonstrations' actions are expert labels too
        learner, hist = train_bc(data, dataclasses.replace(config.bc, seed=config.bc.seed + r), interface,
                                 clock=clock, init=learner if config.warm_start else None)
        rec = {"round": r, "beta": beta, "episodes": n_eps, "new_labels": int(len(new)) if new is not None else
               int(len(data)), "expert_labels": int(expert_labels), "transitions": int(len(data)),
               "rollout_mean_return": float(np.mean(returns)) if returns else None,
               "expert_actions_fraction": (expert_acts / len(new)) if new is not None and len(new) else 1.0,
               "final_loss": hist["loss"][-1], "bc_wall_time_s": hist["wall_time_s"]}
        if evaluate is not None:
            rec["eval"] = evaluate(learner)
            if config.keep == "best" and (best is None or round_rank(rec["eval"]) < best[0]):
                best = (round_rank(rec["eval"]), r, learner)
        history.append(rec)
        bar.update(1)
        bar.set_postfix(labels=expert_labels)
    bar.close()
    env.close()
    selected = config.rounds
    if best is not None:
        _, selected, learner = best
    learner.info.update(expert_labels=int(expert_labels), dagger_rounds=int(config.rounds),
                        estimator=bool(config.estimator), selected_round=int(selected))
    return DAggerResult(learner, data, history, int(expert_labels), time.perf_counter() - t0, int(selected))


DATA_OPTIONAL = ("target_speed", "sent_actions", "action_delay")
"""The optional per-pair arrays of [`Demonstrations`][Demonstrations] that ``dagger_data.npz`` keeps when the data have
them."""


def load_dagger_data(path) -> Demonstrations:
    """The aggregate labels of a [`run_dagger`][run_dagger] run (its directory or its ``dagger_data.npz``) as
    [`Demonstrations`][Demonstrations] (no feedback laws; the optional per-pair arrays the file holds), e.g. to train
    another learner on the same labels with [`hsddp_gym.learning.bc.train_bc`][hsddp_gym.learning.bc.train_bc]. Never
    unpickles."""
    from hsddp_gym.util.io import read_npz

    path = Path(path)
    d = read_npz(path / "dagger_data.npz" if path.is_dir() else path)
    missing = [k for k in ("obs", "actions", "episode") if k not in d]
    if missing:
        raise ValueError(f"path {str(path)!r} is not DAgger data: it lacks {missing}")
    return Demonstrations(d["obs"], d["actions"], d["episode"], None, **{k: d.get(k) for k in DATA_OPTIONAL})


def run_dagger(expert: str, out, seed: int = 0, config: DAggerConfig | None = None, dataset=None,
               demos: int | None = None, fmt: str = "minari", eval_episodes: int = 10,
               env_kwargs: dict | None = None, mpc_options: dict | None = None, progress: bool = True,
               workers: int = 1, env_id: str | None = None) -> dict:
    """DAgger with a built-in expert (``heuristic``, ``mpc`` or ``expert``) and write into ``out``:
    ``policy.npz``, ``dagger_data.npz`` (aggregate labels), ``summary.json``, ``curve.csv`` / ``curve.png``
    (evaluation return after each round vs expert labels).

    Args:
        dataset: optional dataset directory whose first ``demos`` episodes are the round-0 demonstrations.
        workers: processes for each round's rollouts (the result does not depend on it).
        env_id: the env (None: ``config.env_id``, else the env of ``dataset``'s metadata, else Bounding-v0); in
            ``hsddp_gym/Pronking-v0`` the expert must be ``"expert"``: the pronk plan tracker
            ([`pronking_expert`][hsddp_gym.planners.policies.experts.pronking_expert], its plan solved at the env's
            target speed).
    """
    from hsddp_gym.datasets.recording import ENV_ID, check_env_id, solve_expert_plan
    from hsddp_gym.registry import task_of_env_id
    from hsddp_gym.rollout.policies import task_policy_spec
    from hsddp_gym.util.extras import require
    from hsddp_gym.util.io import write_json

    require(["torch"] + (["minari", "h5py"] if dataset is not None and fmt == "minari" else []), "run_dagger")
    config = config or DAggerConfig()
    given = [e for e in (env_id, config.env_id) if e is not None]
    if dataset is not None:
        from hsddp_gym.datasets.storage import read_metadata

        first = dataset[0] if isinstance(dataset, (list, tuple)) else dataset
        given.append(read_metadata(first).get("env_id") or ENV_ID)
    env_id = check_env_id(given[0] if given else None)
    if any(check_env_id(e) != env_id for e in given):
        raise ValueError(f"env_id: the env given, config.env_id and the dataset's env differ: {given}")
    task = task_of_env_id(env_id)
    if task.dataset_expert != "mpc" and expert != "expert" and not (expert == "mpc" and task.motion is not None):
        raise ValueError(f"expert {expert!r} is a {ENV_ID} controller; in {env_id} the expert is 'expert' (the "
                         "task's plan tracker)" + (" or 'mpc' (its motion's MPC)" if task.motion is not None else ""))
    if task.expert is None and expert == "expert":
        raise ValueError(f"in {env_id} the expert is 'mpc' (the terrain-aware MPC), not a plan tracker")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    config = dataclasses.replace(config, seed=int(seed), env_id=env_id,
                                 bc=dataclasses.replace(config.bc, seed=int(seed)))
    env_kwargs = dict(env_kwargs or {})
    files = ["policy.npz", "dagger_data.npz", "summary.json", "curve.csv"]
    plan = None
    if expert == "expert":
        plan = solve_expert_plan(out / "expert_plan.npz", env_id, float(env_kwargs.get("target_speed", 1.0)))
        files.append("expert_plan.npz")
    if config.keep == "best" and eval_episodes <= 0:
        raise ValueError(f"keep='best' chooses the round by its evaluation: eval_episodes must be >= 1, got "
                         f"{eval_episodes}")
    spec = task_policy_spec(expert, env_id, mpc_options, plan_path=str(out / "expert_plan.npz"))
    initial = load_demonstrations(dataset, episodes=demos, fmt=fmt) if dataset is not None else None

    def evaluate(p):
        if eval_episodes <= 0:
            return None
        return eval_brief(evaluate_policy_episodes(p, eval_episodes, 0, env_kwargs, config.max_episode_steps,
                                                   env_id=env_id))

    clock = None
    if config.bc.features == "gait_clock":
        from hsddp_gym.datasets.collection import make_env

        env = make_env(env_kwargs, config.max_episode_steps, env_id=env_id)
        clock = make_gait_clock(EnvInterface.from_env(env), mpc_options if expert == "mpc" else None)
        env.close()
    res = train_dagger(spec, config, initial, env_kwargs, evaluate=evaluate, progress=progress, clock=clock,
                       workers=workers)
    res.policy.save(out / "policy.npz")
    optional = {k: getattr(res.data, k) for k in DATA_OPTIONAL if getattr(res.data, k) is not None}
    write_npz(out / "dagger_data.npz", obs=res.data.obs, actions=res.data.actions, episode=res.data.episode,
              **optional)
    rows = [[h["round"], h["beta"], h["expert_labels"], h["transitions"],
             f"{h['eval']['mean_return']:.6g}" if h.get("eval") else "", f"{h['eval']['std_return']:.6g}"
             if h.get("eval") else "", h["eval"]["falls"] if h.get("eval") else ""] for h in res.history]
    write_csv(out / "curve.csv", ["round", "beta", "expert_labels", "transitions", "mean_return", "std_return",
                                   "falls"], rows)
    evals = [h for h in res.history if h.get("eval")]
    if evals and plot_curve(out / "curve.png", [h["expert_labels"] for h in evals],
                            [h["eval"]["mean_return"] for h in evals], [h["eval"]["std_return"] for h in evals],
                            "expert labels", title=f"DAgger ({expert} expert) vs expert labels"):
        files.append("curve.png")
    summary = {"algo": "dagger", "expert": spec.describe(), "seed": int(seed), "config": {
        **{k: v for k, v in dataclasses.asdict(config).items() if k != "bc"}, "bc": config.bc.to_dict()},
        "initial_dataset": None if dataset is None else str(dataset), "initial_demonstrations":
        None if initial is None else initial.n_episodes, "expert_labels": res.expert_labels,
        "transitions": len(res.data), "history": res.history, "wall_time_s": res.wall_time_s,
        "env_id": env_id, "env_kwargs": env_kwargs, "max_episode_steps": config.max_episode_steps, "files": files,
        "conditions": list(config.conditions), "workers": int(workers), "selected_round": res.selected_round}
    if plan is not None:
        summary["expert_plan"] = plan
    if res.history and res.history[res.selected_round].get("eval"):
        summary["eval"] = res.history[res.selected_round]["eval"]
    write_json(out / "summary.json", summary)
    return summary
