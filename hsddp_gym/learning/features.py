"""Learner inputs: the observation, optionally with the MPC's gait-clock features replayed from the observation
history."""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NU
from hsddp_gym.learning.demonstrations import Demonstrations
from hsddp_gym.planners.policies.base import EnvInterface

FEATURES = ("obs", "gait_clock")
"""Inputs of the MLP: ``obs`` (the observation) or ``gait_clock`` (the observation plus the 7
[`hsddp_gym.planners.policies.mpc.GaitClock.features`][hsddp_gym.planners.policies.mpc.clock.GaitClock.features] of the
MPC's gait clock, rebuilt from the observation history)."""
QUEUE_SLOT_SIZE = NU + 1
"""Inputs per latency-queue slot ([`action_queue_features`][action_queue_features]): an action and a pending mark."""


# ================================================================================================ features
def make_gait_clock(interface: EnvInterface = EnvInterface(), mpc_options=None):
    """The [`hsddp_gym.planners.policies.mpc.GaitClock`][hsddp_gym.planners.policies.mpc.clock.GaitClock] of an
    [`hsddp_gym.planners.policies.mpc.MPCPolicy`][hsddp_gym.planners.policies.mpc.agent.MPCPolicy] built for
    ``interface`` with ``mpc_options`` (an ``MPCOptions``, a record of one as a dict,
    [`from_record`][hsddp_gym.planners.policies.mpc.options.MPCOptions.from_record], or None: the defaults): its gait's
    durations, the control period and the clock's fields of its schedule options."""
    from hsddp_gym.core.schedule import PAPER_BOUNDING_DURATIONS
    from hsddp_gym.planners.policies.mpc import GaitClock, MPCOptions

    o = MPCOptions.from_record(mpc_options)
    durations = o.plan.durations if o.plan.durations is not None else PAPER_BOUNDING_DURATIONS
    return GaitClock(durations, interface.control_dt, o.schedule)


def gait_clock_features(obs: np.ndarray, clock, layout=None) -> np.ndarray:
    """``(T, 7)`` gait-clock features of one episode's observations ``obs (T, d)`` in order: the clock is
    reset, then for every observation updated from its contact flags and pitch rate, read, and ticked
    (exactly what [`MLPPolicy`][hsddp_gym.learning.bc.MLPPolicy] does while acting, and
    [`hsddp_gym.planners.policies.mpc.MPCPolicy`][hsddp_gym.planners.policies.mpc.agent.MPCPolicy] with
    ``touchdown_height=None``: its late-landing rule reads the foot heights of its state estimate,
    [`observe`][hsddp_gym.planners.policies.mpc.clock.GaitClock.observe])."""
    from hsddp_gym.core.observation import DEFAULT_LAYOUT, state_from_observation

    layout = layout if layout is not None else DEFAULT_LAYOUT
    clock = clock.copy()
    clock.reset()
    out = np.zeros((len(obs), clock.N_FEATURES))
    for t, o in enumerate(np.asarray(obs)):
        x, mode, _ = state_from_observation(o, layout)
        clock.observe(mode, x)
        out[t] = clock.features()
        clock.tick()
    return out


def queue_row(pending, slots: int) -> np.ndarray:
    """``(5 slots,)``: one row of [`action_queue_features`][action_queue_features] from the ``pending`` actions ``(d,
    4)`` (oldest first, ``d <= slots``) -- what a policy acting in the env builds from the actions it remembers
    sending."""
    out = np.zeros((int(slots), QUEUE_SLOT_SIZE))
    for j, a in enumerate(pending):
        out[j, :NU], out[j, NU] = a, 1.0
    return out.ravel()


def action_queue_features(sent: np.ndarray, delay: int, slots: int) -> np.ndarray:
    """``(T, 5 slots)`` ([`QUEUE_SLOT_SIZE`][QUEUE_SLOT_SIZE] per slot) latency-queue features of one episode whose
    actions ``sent (T, 4)`` were executed ``delay`` control steps late
    ([`ActionDelay`][hsddp_gym.envs.perturbations.wrappers.ActionDelay]).

    Row ``t`` (the observation at which action ``t`` is chosen) holds the ``delay`` actions sent before it and not
    yet executed, in the order the env will execute them (``sent[t - delay]`` first; the zero torques the
    env executes for the first steps after a reset are zero actions), each followed by a 1 (a pending slot),
    then ``slots - delay`` empty slots (four zeros and a 0). With no delay every row is zero: the learner's input
    is its observation. These are the actions the MPC's latency compensation predicts the state over.

    Raises ``ValueError`` when ``delay > slots`` (the learner cannot see its whole queue).
    """
    sent = np.asarray(sent, dtype=np.float64)
    if sent.ndim != 2 or sent.shape[1] != NU:
        raise ValueError(f"sent must have shape (T, {NU}), got {sent.shape}")
    delay, slots = int(delay), int(slots)
    if not 0 <= delay <= slots:
        raise ValueError(f"the action delay ({delay} control steps) must be in 0 .. action_queue ({slots})")
    T = len(sent)
    out = np.zeros((T, slots, QUEUE_SLOT_SIZE))
    padded = np.concatenate([np.zeros((delay, NU)), sent])  # padded[t + j] = sent[t - delay + j]
    for j in range(delay):
        out[:, j, :NU] = padded[j:j + T]
        out[:, j, NU] = 1.0
    return out.reshape(T, slots * QUEUE_SLOT_SIZE)


def _episode_runs(episode: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` of the contiguous runs of equal episode ids."""
    episode = np.asarray(episode)
    if len(episode) == 0:
        return []
    cuts = np.flatnonzero(np.diff(episode) != 0) + 1
    edges = [0, *cuts.tolist(), len(episode)]
    return list(zip(edges[:-1], edges[1:]))


def build_inputs(demos: Demonstrations, config, clock=None, layout=None) -> np.ndarray:
    """The MLP inputs (float64) of ``demos`` for ``config.features`` (``clock``: a GaitClock for
    ``gait_clock``; each episode -- a contiguous run of one episode id -- starts from a reset clock), then the
    latency queue ([`action_queue_features`][action_queue_features]) when ``config.action_queue``, and the target speed
    [m/s] of each pair's episode appended last when ``config.speed_input``."""
    obs = np.asarray(demos.obs, dtype=np.float64)
    if config.features == "gait_clock":
        if clock is None:
            raise ValueError("features='gait_clock' needs a gait clock")
        feats = np.zeros((len(obs), clock.N_FEATURES))
        for a, b in _episode_runs(demos.episode):
            feats[a:b] = gait_clock_features(obs[a:b], clock, layout)
        obs = np.concatenate([obs, feats], axis=1)
    slots = int(getattr(config, "action_queue", 0))
    if slots:
        if demos.sent_actions is None or demos.action_delay is None:
            raise ValueError("action_queue needs the actions sent and the action delay of every demonstration "
                             "(datasets loaded from their directories, or DAgger rollouts)")
        queue = np.zeros((len(obs), slots * QUEUE_SLOT_SIZE))
        for a, b in _episode_runs(demos.episode):
            delay = np.unique(demos.action_delay[a:b])
            if len(delay) != 1:
                raise ValueError(f"action_delay must be constant within an episode, got {delay.tolist()}")
            queue[a:b] = action_queue_features(demos.sent_actions[a:b], int(delay[0]), slots)
        obs = np.concatenate([obs, queue], axis=1)
    if getattr(config, "speed_input", False):
        if demos.target_speed is None:
            raise ValueError("speed_input needs the target speed of every demonstration (datasets loaded from "
                             "their directories, whose metadata record it)")
        obs = np.concatenate([obs, np.asarray(demos.target_speed, dtype=np.float64)[:, None]], axis=1)
    return obs
