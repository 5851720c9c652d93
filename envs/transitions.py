"""``hsddp_gym/StandToBound-v0``, ``hsddp_gym/BoundPronkBound-v0`` and ``hsddp_gym/BoundToStop-v0``: the Bounding-v0
robot and physics, rewarded for a gait transition (see [`TransitionEnv`][TransitionEnv]).

The task is a mixin, [`TransitionTask`][TransitionTask], on top of an env class of the bounding family, as the jumps'
([`hsddp_gym.envs.jumps`][hsddp_gym.envs.jumps]): [`TransitionEnv`][TransitionEnv] puts it on
[`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] (the exact-LCP simulation),
[`MuJoCoTransitionEnv`][MuJoCoTransitionEnv] on the MuJoCo twin (``hsddp_gym/StandToBoundMuJoCo-v0``,
``hsddp_gym/BoundPronkBoundMuJoCo-v0``, ``hsddp_gym/BoundToStopMuJoCo-v0``). One env, three tasks (``task=``), three
registrations. The physics, action and observation layouts and the reset options are the base class's; the task fixes
the start (the transition plan's: standing at rest for ``"stand_to_bound"``, the backflip's standing start;
Bounding-v0's bounding start for the two others), replaces the reward (the plan's contact schedule and forward-speed
profile, [`contact_schedule`][contact_schedule], [`speed_reference`][speed_reference]), sets the observation clock's
period to the episode and adds a success flag to ``info`` ([`TransitionTask.success`][TransitionTask.success]).

Envs do not import the planners (the package's layers), so [`SCHEDULES`][SCHEDULES] repeats the transition plans'
schedules (``hsddp_gym.planners.motions.transition_problem(task)``, 1 m/s, two cycles per gait segment);
``tests/test_transition_envs.py`` checks that they agree.
"""

from __future__ import annotations

import collections
import math

import gymnasium as gym
import numpy as np

from hsddp_gym.core.conventions import BACK, FRONT, IPITCH, IVX, IVZ, IX, IZ, NQ
from hsddp_gym.core.schedule import PAPER_BOUNDING_DURATIONS
from hsddp_gym.core.task_constants import PRONK_DURATIONS, STAND_DURATION, STOP_DURATION
from hsddp_gym.core.task_constants import TRANSITION_MAX_EPISODE_STEPS as MAX_EPISODE_STEPS
from hsddp_gym.core.task_constants import TRANSITIONS as TASKS
from hsddp_gym.envs.backflip import MAX_RESET_NOISE, BackflipTask, backflip_start_state
from hsddp_gym.envs.bounding import BoundingEnv
from hsddp_gym.envs.mujoco_twin import MuJoCoBoundingEnv
from hsddp_gym.util.validation import check_in_range, check_positive

TARGET_SPEED = 1.0
"""The bounding speed of the plans [m/s]."""
_BS, _FL, _FS, _DS = (False, True), (False, False), (True, False), (True, True)  # (front, back) on the ground
_BOUND = tuple(zip((_BS, _FL, _FS, _FL), PAPER_BOUNDING_DURATIONS))
_PRONK = tuple(zip((_DS, _FL), PRONK_DURATIONS))
SCHEDULES = {
    "stand_to_bound": ((_DS, STAND_DURATION),) + _BOUND * 2,
    "bound_pronk_bound": _BOUND * 2 + _PRONK * 2 + ((_DS, 0.05),) + _BOUND * 2,
    "bound_to_stop": _BOUND * 2 + ((_DS, STOP_DURATION),),
}
"""Per task, the plan's phases ``((front_down, back_down), duration [s])`` (``transition_problem(task, 1.0, 2)``:
stand to bound ``DS(250 ms) (BS FL FS FL) x 2``; bound, pronk, bound ``(BS FL FS FL) x 2 (DS FL) x 2 DS(50 ms)
(BS FL FS FL) x 2``; bound to stop ``(BS FL FS FL) x 2 DS(400 ms)``)."""
SPEED_KNOTS = {
    "stand_to_bound": ((0.0, 0.0), (0.25, 0.4), (0.546, 0.7), (0.842, 1.0)),
    "bound_pronk_bound": ((0.0, 1.0),),
    "bound_to_stop": ((0.0, 1.0), (0.296, 1.0), (0.592, 0.4), (0.992, 0.0)),
}
"""Per task, the forward-speed reference ``(t [s], v [m/s])``, linear between knots and constant after the last: the
speeds the plan's phases end at (stand to bound: from rest to 0.4 m/s by the end of the double stance, then 0.7 and
1 m/s at the ends of the two cycles; bound to stop: 1 m/s, then 0.4 m/s, then rest)."""
EPISODE_DURATIONS = {"stand_to_bound": 1.5, "bound_pronk_bound": 2.0, "bound_to_stop": 1.5}
"""Episode length per task [s]: the plan (0.84 s, 1.59 s, 0.99 s) and a hold of at least 0.4 s (bounding on at
1 m/s, standing at rest); the default observation clock period."""
WINDOW_STEPS = 60
"""Success: the window, the last this many control steps (0.3 s, one bounding cycle), judged as a gait."""
SPEED_TOLERANCE = 0.3
"""Success (bounding): the mean forward speed over the window within this of [`TARGET_SPEED`][TARGET_SPEED] [m/s]."""
MIN_SINGLE_STANCE_STEPS = 4
"""Success (bounding): at least this many control steps of back stance alone and of front stance alone in the
window."""
MAX_DOUBLE_STANCE_FRACTION = 0.2
"""Success (bounding): at most this fraction of the window with both feet on the ground."""
PRONK_STANCE_STEPS = 6
"""Success (bound, pronk, bound): a double stance of at least this many consecutive control steps (30 ms) counts as a
pronk stance (the bound has none: its stances are single)."""
MIN_PRONK_STANCES = 2
"""Success (bound, pronk, bound): at least this many pronk stances."""
REST_MAX_SPEED = 0.1
"""Success (bound to stop): the trunk speed ``sqrt(vx^2 + vz^2)`` at most this [m/s] at the end."""
REST_MAX_PITCH_RATE = 0.5
"""Success (bound to stop): ``|pitch rate|`` at most this [rad/s] at the end."""
REST_MAX_PITCH = 0.3
"""Success (bound to stop): ``|pitch|`` at most this [rad] at the end."""
REST_MIN_HEIGHT = 0.15
"""Success (bound to stop): the trunk centre at least this high [m] at the end."""
DEFAULT_SPEED_REWARD = 1.0
"""Largest per-step reward for the forward speed on its reference."""
DEFAULT_GAIT_REWARD = 1.0
"""Per-step reward for both feet's contacts as the schedule has them (half for one)."""
SPEED_SIGMA = 0.3
"""Width [m/s] of the speed term ``exp(-((vx - v_ref(t)) / sigma)^2)``."""


def contact_schedule(task: str, t: float) -> tuple[bool, bool]:
    """``(front_down, back_down)`` of ``task``'s plan at time ``t`` [s]; after the plan, its last bounding cycle
    repeated (stand to bound; bound, pronk, bound) or the final double stance (bound to stop)."""
    phases = SCHEDULES[task]
    total = sum(d for _, d in phases)
    if t >= total:
        if task == "bound_to_stop":
            return _DS
        cycle = sum(PAPER_BOUNDING_DURATIONS)
        t = total - cycle + (t - total) % cycle
    s = 0.0
    for contacts, d in phases:
        s += d
        if t < s - 1e-12:
            return contacts
    return phases[-1][0]


def speed_reference(task: str, t: float) -> float:
    """The forward-speed reference of ``task`` at time ``t`` [s] ([`SPEED_KNOTS`][SPEED_KNOTS])."""
    knots = np.array(SPEED_KNOTS[task])
    return float(np.interp(t, knots[:, 0], knots[:, 1]))


def plan_duration(task: str) -> float:
    """The duration of ``task``'s plan [s]."""
    return float(sum(d for _, d in SCHEDULES[task]))


class TransitionTask:
    r"""The gait-transition task, a mixin on an env of the bounding family ([`TransitionEnv`][TransitionEnv],
    [`MuJoCoTransitionEnv`][MuJoCoTransitionEnv]).

    Arguments it adds or changes (every other argument is the base env's):

    | parameter | default | description |
    |---|---|---|
    | ``task`` | ``"stand_to_bound"`` | ``"stand_to_bound"``, ``"bound_pronk_bound"`` or ``"bound_to_stop"`` |
    | ``speed_reward`` | 1.0 | largest per-step reward for the forward speed on its reference |
    | ``gait_reward`` | 1.0 | per-step reward for both feet's contacts on the schedule |
    | ``forward_reward_weight`` | 0.0 | the base env's speed-tracking term (off) |
    | ``healthy_reward`` | 0.0 | the base env's per-step healthy reward (off) |
    | ``gait_period`` | the episode | period of the observation's clock [s] (1.5 s, 2 s, 1.5 s) |
    | ``reset_noise_scale`` | 0.01 | noise of the start (standing: at most 0.05) |
    """

    def __init__(self, *, task: str = "stand_to_bound", speed_reward: float = DEFAULT_SPEED_REWARD,
                 gait_reward: float = DEFAULT_GAIT_REWARD, forward_reward_weight: float = 0.0,
                 healthy_reward: float = 0.0, gait_period: float | None = None, reset_noise_scale: float = 0.01,
                 **kwargs) -> None:
        if not isinstance(task, str) or task not in TASKS:
            raise ValueError(f"task must be one of {TASKS}, got {task!r}")
        self.task = task
        self.speed_reward = check_positive(speed_reward, "speed_reward", allow_zero=True)
        self.gait_reward = check_positive(gait_reward, "gait_reward", allow_zero=True)
        if task == "stand_to_bound":
            check_in_range(reset_noise_scale, 0.0, MAX_RESET_NOISE, "reset_noise_scale")
        gait_period = EPISODE_DURATIONS[task] if gait_period is None else gait_period
        self.plan_duration = plan_duration(task)
        self._reset_task(0.0)
        super().__init__(forward_reward_weight=forward_reward_weight, healthy_reward=healthy_reward,
                         gait_period=check_in_range(gait_period, 0.05, 60.0, "gait_period"),
                         target_speed=TARGET_SPEED, reset_noise_scale=reset_noise_scale, **kwargs)
        if task == "stand_to_bound":
            self.init_state = backflip_start_state(self.robot)
            self.sim.set_state(self.init_state)
            self._update_feet(at_reset=True)

    def _reset_task(self, t0: float) -> None:
        self._t0 = float(t0)
        self._fell = False
        self._window: collections.deque = collections.deque(maxlen=WINDOW_STEPS)  # (front, back, x)
        self._double_run = 0
        self._pronk_stances = 0
        self._task_rewards = (0.0, 0.0)
        self._step_start = 0.0  # task_time at the start of the step in progress

    # ------------------------------------------------------------------ task state
    @property
    def task_time(self) -> float:
        """Time since the episode's start [s]."""
        return float(self.time) - self._t0

    def _bounding(self) -> bool:
        """The window is a bound at the target speed: full, single stances of both feet, few double stances, the
        mean forward speed within [`SPEED_TOLERANCE`][SPEED_TOLERANCE]."""
        if len(self._window) < WINDOW_STEPS:
            return False
        w = np.array(self._window)
        front, back = w[:, 0] > 0.5, w[:, 1] > 0.5
        speed = (w[-1, 2] - w[0, 2]) / ((WINDOW_STEPS - 1) * float(self.dt))
        return bool(np.sum(back & ~front) >= MIN_SINGLE_STANCE_STEPS
                    and np.sum(front & ~back) >= MIN_SINGLE_STANCE_STEPS
                    and np.mean(front & back) <= MAX_DOUBLE_STANCE_FRACTION
                    and abs(speed - TARGET_SPEED) <= SPEED_TOLERANCE)

    def _at_rest(self) -> bool:
        """Standing still: both feet down over the whole window, and now slow, level and up."""
        if len(self._window) < WINDOW_STEPS:
            return False
        w = np.array(self._window)
        x = self.sim.x
        return bool(np.all(w[:, 0] > 0.5) and np.all(w[:, 1] > 0.5)
                    and math.hypot(float(x[IVX]), float(x[IVZ])) <= REST_MAX_SPEED
                    and abs(float(x[NQ + IPITCH])) <= REST_MAX_PITCH_RATE
                    and abs(float(x[IPITCH])) <= REST_MAX_PITCH and float(x[IZ]) >= REST_MIN_HEIGHT)

    def success(self) -> bool:
        """The task's success now (its value at an episode's last step is the episode's): no fall (no termination)
        and past the plan's duration, and

        * ``"stand_to_bound"``: bounding over the last [`WINDOW_STEPS`][WINDOW_STEPS] control steps (0.3 s): at least
          [`MIN_SINGLE_STANCE_STEPS`][MIN_SINGLE_STANCE_STEPS] steps of back stance alone and of front stance alone, at
          most [`MAX_DOUBLE_STANCE_FRACTION`][MAX_DOUBLE_STANCE_FRACTION] of the window in double stance, the mean
          forward speed within [`SPEED_TOLERANCE`][SPEED_TOLERANCE] of [`TARGET_SPEED`][TARGET_SPEED];
        * ``"bound_pronk_bound"``: at least [`MIN_PRONK_STANCES`][MIN_PRONK_STANCES] pronk stances (double stances of at
        least
          [`PRONK_STANCE_STEPS`][PRONK_STANCE_STEPS] steps) in the episode, and bounding over the last window as above;
        * ``"bound_to_stop"``: at rest standing: both feet down over the last window, and now trunk speed at most
          [`REST_MAX_SPEED`][REST_MAX_SPEED], pitch rate at most [`REST_MAX_PITCH_RATE`][REST_MAX_PITCH_RATE],
          ``|pitch|`` at most [`REST_MAX_PITCH`][REST_MAX_PITCH], trunk centre at least
          [`REST_MIN_HEIGHT`][REST_MIN_HEIGHT] high."""
        if self._fell or self._invalid or self.task_time < self.plan_duration - 1e-9:
            return False
        if self.task == "bound_to_stop":
            return self._at_rest()
        if self.task == "bound_pronk_bound" and self._pronk_stances < MIN_PRONK_STANCES:
            return False
        return self._bounding()

    def _get_info(self) -> dict:
        info = super()._get_info()
        speed, gait = self._task_rewards
        info["reward_speed"] = speed
        info["reward_gait"] = gait
        info["speed_reference"] = speed_reference(self.task, self.task_time)
        info["pronk_stances"] = int(self._pronk_stances)
        info["success"] = self.success()
        return info

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """The plan's start with a seeded noise: Bounding-v0's reset (the noisy paper initial state) for
        ``"bound_pronk_bound"`` and ``"bound_to_stop"``, the backflip's noisy standing start for
        ``"stand_to_bound"`` (`_standing_start`); or
        ``options["state"]``. The other options (``time``, ``push``) are the base env's."""
        self._reset_task(0.0)
        if self.task == "stand_to_bound" and (options is None or (isinstance(options, dict)
                                                                  and options.get("state") is None)):
            gym.Env.reset(self, seed=seed)  # seeds self.np_random
            options = {**(options or {}), "state": BackflipTask._standing_start(self)}
            seed = None
        obs, info = super().reset(seed=seed, options=options)
        self._reset_task(float(self.time))
        info["pronk_stances"] = 0
        info["speed_reference"] = speed_reference(self.task, 0.0)
        info["success"] = self.success()
        return obs, info

    def _begin_step(self, action) -> None:
        self._step_start = self.task_time  # the schedule's time of this step's start
        super()._begin_step(action)

    def _end_step(self, impulse) -> tuple:
        """The base env's step (its control cost; its speed and healthy terms are off by default) plus the speed
        and gait terms (class docstring of [`TransitionEnv`][TransitionEnv])."""
        t = self._step_start
        obs, reward, terminated, truncated, info = super()._end_step(impulse)
        x = self.sim.x
        speed = gait = 0.0
        if not self._invalid:
            front, back = bool(self._contact[FRONT]), bool(self._contact[BACK])
            self._window.append((float(front), float(back), float(x[IX])))
            if front and back:
                self._double_run += 1
                if self._double_run == PRONK_STANCE_STEPS:
                    self._pronk_stances += 1
            else:
                self._double_run = 0
            v_ref = speed_reference(self.task, t + float(self.dt))
            speed = self.speed_reward * math.exp(-((float(x[IVX]) - v_ref) / SPEED_SIGMA) ** 2)
            want = contact_schedule(self.task, t)
            gait = self.gait_reward * 0.5 * ((front == want[FRONT]) + (back == want[BACK]))
        if terminated:
            self._fell = True
            speed = gait = 0.0
        self._task_rewards = (speed, gait)
        info["reward_speed"] = speed
        info["reward_gait"] = gait
        info["speed_reference"] = speed_reference(self.task, self.task_time)
        info["pronk_stances"] = int(self._pronk_stances)
        info["success"] = self.success()
        return obs, float(reward + speed + gait), terminated, truncated, info


class TransitionEnv(TransitionTask, BoundingEnv):
    r"""Planar MIT Mini Cheetah changing gait: from standing into a bound, from a bound into a pronk and back, or
    from a bound to a stop.

    ## Description
    The robot, physics, action space, observation layout, info and reset options of
    [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] (``hsddp_gym/Bounding-v0``), with the transition task
    ([`TransitionTask`][TransitionTask]) of one of the HS-DDP transition plans
    ([`hsddp_gym.planners.motions`][hsddp_gym.planners.motions], ``plan_transition``, 1 m/s, two cycles per gait
    segment):

    * ``task="stand_to_bound"`` (``hsddp_gym/StandToBound-v0``): from standing at rest, reach bounding at 1 m/s
      (plan: a 250 ms double stance that accelerates, then two bounding cycles at 0.7 and 1 m/s; 0.84 s);
    * ``task="bound_pronk_bound"`` (``hsddp_gym/BoundPronkBound-v0``): bounding at 1 m/s, two pronk cycles (100 ms
      double stance, 80 ms flight), bound again (1.59 s);
    * ``task="bound_to_stop"`` (``hsddp_gym/BoundToStop-v0``): bounding at 1 m/s, slow down, land on both feet and
      come to rest standing (0.99 s).

    ## Action space
    ``Box(-1, 1, (4,), float32)``: normalized joint torques, as Bounding-v0 (33 N m a full action, 200 Hz).

    ## Observation space
    ``Box((17,), float32)``, Bounding-v0's layout; the clock (indices 15-16, ``sin, cos 2 pi t / gait_period``) runs
    once per episode, ``gait_period`` = the episode (1.5 s, 2 s, 1.5 s) by default: it tells the time since the
    start, hence where in the plan's schedule the robot should be.

    ## Rewards
    ``reward = speed_reward * exp(-((vx - v_ref(t)) / 0.3)^2) + gait_reward * (matches / 2) - ctrl_cost_weight *
    ||a||^2`` (defaults 1, 1, 0.1): ``v_ref(t)`` the plan's forward-speed profile ([`speed_reference`][speed_reference]:
    stand to bound from 0 to 1 m/s, bound-pronk-bound 1 m/s, bound to stop from 1 m/s to 0), ``matches`` the number of
    feet (0-2) whose contact flag is what the plan's contact schedule has at ``t``
    ([`contact_schedule`][contact_schedule]; after the plan its last bounding cycle repeated, or the double stance of
    the stop). Bounding-v0's speed-tracking and healthy terms are off. The terms are in ``info``: ``reward_speed``,
    ``reward_gait``, ``reward_ctrl`` (and the base's ``reward_forward``, ``reward_healthy``, 0 by default).

    ## Starting state
    The plan's start with a seeded noise of scale ``s = reset_noise_scale`` (default 0.01): ``"stand_to_bound"``
    the backflip's standing start (standing at rest at 0.26 m, feet under the hips; ``U(-s, s)`` on ``q`` then the
    feet put back on the ground, ``s N(0, 1)`` on the trunk velocities, ``s`` at most 0.05); the two others
    Bounding-v0's (the paper's initial state, mid back stance at 0.9 m/s; ``U(-s, s)`` on ``q``, ``s N(0, 1)`` on
    ``v``). The reset options (``state``, ``time``, ``push``) are Bounding-v0's.

    ## Episode end
    ``terminated`` on a fall: Bounding-v0's (the trunk centre leaves ``healthy_z_range`` (0.12, 0.5) m, the pitch
    leaves ``healthy_pitch_range`` (-0.8, 0.8) rad, an invalid state). ``truncated`` by the registered
    ``TimeLimit``: 300, 400, 300 control steps (1.5 s, 2 s, 1.5 s: the plan and at least 0.4 s more).

    ## Success
    ``info["success"]`` at every step (its value at the last step of an episode is the episode's,
    [`TransitionTask.success`][TransitionTask.success]): no fall, past the plan's duration, and over the last 60 control
    steps (0.3 s) bounding at 1 m/s (back stance alone and front stance alone at least 4 steps each, double stance at
    most 20 %, mean speed within 0.3 m/s of 1 m/s; bound-pronk-bound also at least 2 double stances of 30 ms or more in
    the episode) or, for the stop, both feet down throughout and at the end trunk speed at most 0.1 m/s, pitch rate at
    most 0.5 rad/s, ``|pitch|`` at most 0.3 rad, trunk centre at least 0.15 m high.

    ## Info
    Bounding-v0's keys plus ``reward_speed``, ``reward_gait``, ``speed_reference`` (float), ``pronk_stances``
    (int) and ``success`` (bool), the same keys at reset and at every step.

    ## Arguments
    [`TransitionTask`][TransitionTask]'s and every other argument of
    [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv], all JSON-serializable (``target_speed`` is set to 1 m/s).
    Vector env: ``gym.make_vec(ID, num_envs=N)`` builds
    [`TransitionVectorEnv`][hsddp_gym.envs.task_vector.TransitionVectorEnv] (the physics of all robots in one compiled
    call, bit-identical to N single envs).

    ## Version history
    * v0: initial release.
    """


class MuJoCoTransitionEnv(TransitionTask, MuJoCoBoundingEnv):
    """``hsddp_gym/StandToBoundMuJoCo-v0``, ``hsddp_gym/BoundPronkBoundMuJoCo-v0`` and
    ``hsddp_gym/BoundToStopMuJoCo-v0``: [`TransitionEnv`][TransitionEnv]'s task (start, reward, termination, success,
    arguments) simulated by MuJoCo, [`MuJoCoBoundingEnv`][hsddp_gym.envs.mujoco_twin.MuJoCoBoundingEnv] (its
    contact-model arguments too; needs the extra ``mujoco``)."""


__all__ = ["TASKS", "TARGET_SPEED", "SCHEDULES", "SPEED_KNOTS", "EPISODE_DURATIONS", "MAX_EPISODE_STEPS",
           "WINDOW_STEPS", "SPEED_TOLERANCE", "MIN_SINGLE_STANCE_STEPS", "MAX_DOUBLE_STANCE_FRACTION",
           "PRONK_STANCE_STEPS", "MIN_PRONK_STANCES", "REST_MAX_SPEED", "REST_MAX_PITCH_RATE", "REST_MAX_PITCH",
           "REST_MIN_HEIGHT", "DEFAULT_SPEED_REWARD", "DEFAULT_GAIT_REWARD", "SPEED_SIGMA", "contact_schedule",
           "speed_reference", "plan_duration", "TransitionTask", "TransitionEnv", "MuJoCoTransitionEnv"]
