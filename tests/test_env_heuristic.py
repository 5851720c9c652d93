"""The heuristic bounding controller, driven by the env's own contact events, bounds in ``Bounding-v0``.

``HeuristicPolicy`` acts from the observation only (state and contact flags, see
:func:`hsddp_gym.core.observation.state_from_observation`) plus its own memory: a per-leg stance/swing state
machine started by the observed touchdowns
(:class:`hsddp_gym.planners.policies.heuristic.ContactEventBoundingController`).
The schedule-driven warm-start controller (:class:`hsddp_gym.planners.policies.heuristic.HeuristicBoundingController`),
fed the contact mode from the flags, falls within about a second: with state-based contacts a stance lasts until
the leg force vanishes (~140 ms instead of 80 ms) and the trunk pitches over. The fixed stance time with an
active lift-off is what makes the difference (a 140 ms stance falls too, see below).

Bounding cycles are counted from the contact flags: back stance, flight, front stance, flight, in this
order with no double stance in between (runs shorter than 5 ms are ignored).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym.core.conventions import BACK, FRONT, Mode, mode_from_contacts
from hsddp_gym.core.observation import state_from_observation
from hsddp_gym.planners.policies.heuristic import (
    ContactEventBoundingController,
    ContactEventGains,
    HeuristicGains,
    HeuristicPolicy,
)

STEPS = 400  # 2 s at the default 5 ms control period, about 12 bounding cycles


def phase_runs(modes: list[Mode], dt: float, min_duration: float = 0.005) -> list[tuple[Mode, float]]:
    """Consecutive runs ``(mode, duration [s])`` of a per-step mode list; runs shorter than
    ``min_duration`` (contact blips) are merged into the previous run."""
    runs: list[list] = []
    for m in modes:
        if runs and runs[-1][0] == m:
            runs[-1][1] += dt
        else:
            runs.append([m, dt])
    merged: list[list] = []
    for m, d in runs:
        if merged and (d < min_duration - 1e-9 or merged[-1][0] == m):
            merged[-1][1] += d
        else:
            merged.append([m, d])
    return [(m, d) for m, d in merged]


def bounding_cycles(modes: list[Mode], dt: float) -> int:
    """Number of complete bounding cycles: back stance, flight, front stance, flight, in this order with no
    double stance in between (phases shorter than 5 ms are ignored)."""
    seq = [m for m, _ in phase_runs(modes, dt)]
    cycle = [Mode.BACK_STANCE, Mode.FLIGHT, Mode.FRONT_STANCE, Mode.FLIGHT]
    count, i = 0, 0
    while i + 4 <= len(seq):
        if seq[i:i + 4] == cycle:
            count += 1
            i += 4
        else:
            i += 1
    return count


def run_policy(env, policy, seed: int, steps: int = STEPS) -> dict:
    """Run ``policy`` from ``reset(seed)``; per-step contact modes from the observation and from ``info``."""
    layout = env.unwrapped.observation_layout
    obs, info = env.reset(seed=seed)
    policy.reset()
    x0 = info["x_position"]
    obs_modes, info_modes = [], []
    terminated = truncated = False
    n = 0
    while n < steps and not (terminated or truncated):
        obs, _, terminated, truncated, info = env.step(policy(obs))
        n += 1
        obs_modes.append(state_from_observation(obs, layout)[1])
        info_modes.append(mode_from_contacts(*info["contact"]))
    dt = float(env.unwrapped.dt)
    return {"terminated": terminated, "truncated": truncated, "steps": n, "time": n * dt,
            "speed": (info["x_position"] - x0) / (n * dt), "obs_modes": obs_modes, "info_modes": info_modes,
            "dt": dt}


@pytest.fixture(scope="module")
def env():
    return gym.make("hsddp_gym/Bounding-v0")  # every default: frame_skip 5, reset noise 0.01, 1 m/s


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_heuristic_policy_bounds_from_its_contact_events(env, seed):
    res = run_policy(env, HeuristicPolicy.from_env(env), seed)
    assert not res["terminated"], f"fell after {res['time']:.3f} s"
    assert res["steps"] == STEPS
    cycles = bounding_cycles(res["obs_modes"], res["dt"])
    runs = [(m.short, round(d * 1e3)) for m, d in phase_runs(res["obs_modes"], res["dt"])]
    assert cycles >= 5, f"only {cycles} bounding cycles: {runs}"
    assert res["obs_modes"] == res["info_modes"]  # the observation's flags are the env's contact events
    assert 0.5 < res["speed"] < 1.5
    # a bound, not a gallop or a walk: little double stance
    assert np.mean([m == Mode.DOUBLE_STANCE for m in res["obs_modes"]]) < 0.05


def test_heuristic_policy_survives_a_whole_episode(env):
    res = run_policy(env, HeuristicPolicy.from_env(env), seed=7, steps=10_000)
    assert res["truncated"] and not res["terminated"] and res["steps"] == 1000
    assert bounding_cycles(res["obs_modes"], res["dt"]) >= 15
    assert 0.7 < res["speed"] < 1.3


def test_stances_last_the_fixed_stance_time(env):
    res = run_policy(env, HeuristicPolicy.from_env(env), seed=0, steps=200)
    stances = [d for m, d in phase_runs(res["obs_modes"], res["dt"])[1:-1]
               if m in (Mode.BACK_STANCE, Mode.FRONT_STANCE)]
    # 50 ms of pushing, then the folding leg leaves the ground within about two control periods
    assert len(stances) >= 6
    assert all(0.045 <= d <= 0.075 for d in stances), stances


def test_without_the_active_lift_off_the_policy_falls(env):
    """A 140 ms stance (the passive stance of the schedule-driven gains) tips the trunk over."""
    policy = HeuristicPolicy.from_env(env, gait_gains=ContactEventGains(stance_duration=0.14))
    res = run_policy(env, policy, seed=0)
    assert res["terminated"] and bounding_cycles(res["obs_modes"], res["dt"]) < 5


def test_schedule_driven_controller_fed_the_contact_flags_falls(env):
    """Documents why the env needs the event-driven gait: the warm-start controller falls within ~1 s."""
    policy = HeuristicPolicy.from_env(env)
    layout = env.unwrapped.observation_layout
    controller = policy.controller  # HeuristicBoundingController (schedule-driven, torque(x, mode))
    last = BACK

    class Flags:
        def reset(self):
            pass

        def __call__(self, obs):
            nonlocal last
            x, mode, _ = state_from_observation(obs, layout)
            if mode in (Mode.BACK_STANCE, Mode.FRONT_STANCE):
                last = mode.feet[0]
            nxt = (FRONT if last == BACK else BACK) if mode == Mode.FLIGHT else None
            return policy.interface.action_from_torque(controller.torque(x, mode, nxt))

    res = run_policy(env, Flags(), seed=0)
    assert res["terminated"] and res["time"] < 1.5


def test_policy_copies_keep_their_own_gait_memory(env):
    policy = HeuristicPolicy.from_env(env)
    obs, _ = env.reset(seed=0)
    policy.reset()
    policy(obs)
    twin = policy.spawn()
    assert twin.gait is not policy.gait and twin.gait.leg_state is None
    assert policy.gait.leg_state is not None


def test_contact_event_gains_are_checked():
    with pytest.raises(ValueError, match="stance_duration"):
        ContactEventGains(stance_duration=0.0)
    with pytest.raises(ValueError, match="kp"):
        ContactEventGains(kp=(1.0, 2.0))
    with pytest.raises(TypeError, match="ContactEventGains"):
        ContactEventBoundingController(0.005, gains=HeuristicGains())
    with pytest.raises(ValueError, match="dt"):
        ContactEventBoundingController(0.0)


@pytest.mark.parametrize("modes, expected", [
    ([Mode.BACK_STANCE] * 6 + [Mode.FLIGHT] * 6 + [Mode.FRONT_STANCE] * 6 + [Mode.FLIGHT] * 6, 1),
    (([Mode.BACK_STANCE] * 6 + [Mode.FLIGHT] * 6 + [Mode.FRONT_STANCE] * 6 + [Mode.FLIGHT] * 6) * 3, 3),
    ([Mode.BACK_STANCE] * 6 + [Mode.FLIGHT] * 6 + [Mode.FRONT_STANCE] * 2 + [Mode.FLIGHT] * 6, 0),
    ([Mode.BACK_STANCE] * 6 + [Mode.DOUBLE_STANCE] * 6 + [Mode.FRONT_STANCE] * 6 + [Mode.FLIGHT] * 6, 0),
    ([Mode.BACK_STANCE] * 6 + [Mode.FLIGHT] * 6 + [Mode.FRONT_STANCE] * 6 + [Mode.DOUBLE_STANCE] * 2
     + [Mode.FRONT_STANCE] * 6 + [Mode.FLIGHT] * 6, 1),
])
def test_bounding_cycle_counter(modes, expected):
    assert bounding_cycles(modes, 1e-3) == expected
