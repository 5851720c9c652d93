"""``hsddp_gym/GapJump-v0`` and ``hsddp_gym/BoxJump-v0``: the Bounding-v0 robot and physics on a terrain, rewarded for
jumping over a 0.3 m gap or onto a 0.1 m box and bounding on (see [`JumpEnv`][JumpEnv]).

The task is a mixin, [`JumpTask`][JumpTask], on top of an env class of the bounding family, as the backflip's
([`hsddp_gym.envs.backflip`][hsddp_gym.envs.backflip]): [`JumpEnv`][JumpEnv] puts it on
[`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] (the exact-LCP simulation), [`MuJoCoJumpEnv`][MuJoCoJumpEnv] on the
MuJoCo twin (``hsddp_gym/GapJumpMuJoCo-v0``, ``hsddp_gym/BoxJumpMuJoCo-v0``). One env, two tasks (``task="gap_jump"`` or
``"box_jump"``), two registrations. The physics, action and observation layouts, the start (Bounding-v0's: the paper's
initial state, bounding at 0.9 m/s, with a seeded noise) and the reset options are the base class's; the task fixes the
terrain, changes the reward (progress across the obstacle, then upright on the far side), adds a fall (a foot in the
gap), sets the observation clock's period to the episode (2 s) and adds a success flag to ``info``
([`JumpTask.success`][JumpTask.success]).

The terrain is the jump plan's
([`hsddp_gym.core.task_constants.jump_terrain`][hsddp_gym.core.task_constants.jump_terrain], at 1 m/s after
[`JUMP_APPROACH_CYCLES`][hsddp_gym.core.task_constants.JUMP_APPROACH_CYCLES] bounding cycles), the obstacle's constants
([`GAP_WIDTH`][hsddp_gym.core.task_constants.GAP_WIDTH], ``BOX_HEIGHT``, ``BOX_LENGTH``) the planners' too. """

from __future__ import annotations

import math

import numpy as np

from hsddp_gym.core.conventions import IPITCH, IX, IZ, NQ
from hsddp_gym.core.task_constants import JUMPS as TASKS
from hsddp_gym.core.task_constants import jump_terrain
from hsddp_gym.envs.bounding import BoundingEnv
from hsddp_gym.envs.mujoco_twin import MuJoCoBoundingEnv
from hsddp_gym.util.validation import check_in_range, check_positive

EPISODE_DURATION = 2.0
"""Episode length [s]: the approach and the jump (1.0 s in the plan), two cycles on the far side (0.66 s) and a
third of a second more; the default observation clock period."""
GAP_FOOT_DEPTH = 0.02
"""A foot this far [m] below the gap's rims while over the gap is in the gap: a fall."""
SUCCESS_BEYOND = 0.3
"""Success: the trunk at least this far [m] beyond the obstacle's far edge (the gap's far rim, the box's near
edge), and both feet beyond it."""
SUCCESS_MIN_HEIGHT = 0.15
"""Success: the trunk centre at least this high [m] above the ground under it at every step of the hold window."""
SUCCESS_MAX_PITCH = 0.6
"""Success: ``|pitch|`` at most this [rad] at every step of the hold window."""
HOLD_STEPS = 50
"""Success: the hold window, the last this many control steps (0.25 s) upright beyond the obstacle."""
DEFAULT_CROSSING_REWARD = 10.0
"""Reward for getting across, paid as the trunk's x progresses to [`SUCCESS_BEYOND`][SUCCESS_BEYOND] past the far edge
(taken back on a fall)."""
DEFAULT_UPRIGHT_REWARD = 1.0
"""Largest per-step reward for being upright beyond the obstacle."""
UPRIGHT_PITCH_SIGMA = 0.3
"""Width [rad] of the upright term's pitch factor ``exp(-(pitch / sigma)^2)``."""





def far_edge(task: str) -> float:
    """The x [m] past which the robot is across: the gap's far rim, the box's near edge."""
    terrain = jump_terrain(task)
    return float(terrain.edges[1] if task == "gap_jump" else terrain.edges[0])


class JumpTask:
    r"""The jump task, a mixin on an env of the bounding family ([`JumpEnv`][JumpEnv],
    [`MuJoCoJumpEnv`][MuJoCoJumpEnv]).

    Arguments it adds or changes (every other argument is the base env's; ``terrain`` is set by ``task``):

    | parameter | default | description |
    |---|---|---|
    | ``task`` | ``"gap_jump"`` | ``"gap_jump"`` (a 0.3 m gap) or ``"box_jump"`` (a 0.1 m box) |
    | ``crossing_reward`` | 10.0 | reward of getting across, paid with the trunk's progress |
    | ``upright_reward`` | 1.0 | largest per-step reward for being upright beyond the obstacle |
    | ``forward_reward_weight`` | 0.0 | the base env's speed-tracking term (off) |
    | ``healthy_reward`` | 0.0 | the base env's per-step healthy reward (off) |
    | ``gait_period`` | 2.0 | period of the observation's clock [s]: the episode |
    """

    def __init__(self, *, task: str = "gap_jump", crossing_reward: float = DEFAULT_CROSSING_REWARD,
                 upright_reward: float = DEFAULT_UPRIGHT_REWARD, forward_reward_weight: float = 0.0,
                 healthy_reward: float = 0.0, gait_period: float = EPISODE_DURATION, **kwargs) -> None:
        if not isinstance(task, str) or task not in TASKS:
            raise ValueError(f"task must be one of {TASKS}, got {task!r}")
        if kwargs.get("terrain") is not None:
            raise ValueError("terrain is set by task (the jump plan's terrain); leave it None")
        kwargs.pop("terrain", None)
        self.task = task
        self.crossing_reward = check_positive(crossing_reward, "crossing_reward", allow_zero=True)
        self.upright_reward = check_positive(upright_reward, "upright_reward", allow_zero=True)
        self.far_edge = far_edge(task)
        self._target_x = self.far_edge + SUCCESS_BEYOND
        self._reset_task(0.0)
        super().__init__(forward_reward_weight=forward_reward_weight, healthy_reward=healthy_reward,
                         gait_period=check_in_range(gait_period, 0.05, 60.0, "gait_period"),
                         terrain=jump_terrain(task), **kwargs)

    def _reset_task(self, x0: float) -> None:
        self._x0 = float(x0)
        self._progress = 0.0
        self._paid = 0.0
        self._fell = False
        self._hold = 0  # consecutive control steps upright and across
        self._task_rewards = (0.0, 0.0)

    # ------------------------------------------------------------------ task state
    def _foot_in_gap(self) -> bool:
        terrain = self.terrain
        for x, z in self.robot.foot_positions(self.sim.x[:NQ]).tolist():
            if terrain.gap_at(x) and z < terrain.support_height(x) - GAP_FOOT_DEPTH:
                return True
        return False

    def _healthy(self, valid: bool) -> bool:
        return super()._healthy(valid) and not self._foot_in_gap()

    def _height_above_ground(self) -> float:
        x = self.sim.x
        return float(x[IZ]) - self.ground_height(float(x[IX]))

    def _across(self) -> bool:
        x = self.sim.x
        feet = self.robot.foot_positions(x[:NQ])
        return bool(float(x[IX]) >= self._target_x and np.all(feet[:, 0] > self.far_edge))

    def success(self) -> bool:
        """The task's success now: no fall (no termination: the trunk never dropped below the healthy height over the
        ground under it, no foot ever went into the gap), and for the last [`HOLD_STEPS`][HOLD_STEPS] control steps
        across (the trunk at least [`SUCCESS_BEYOND`][SUCCESS_BEYOND] past the far edge, both feet past it), upright
        (``|pitch| <= SUCCESS_MAX_PITCH``) and up (trunk centre at least [`SUCCESS_MIN_HEIGHT`][SUCCESS_MIN_HEIGHT]
        above the ground under it)."""
        return bool(not self._fell and self._hold >= HOLD_STEPS)

    def _get_info(self) -> dict:
        info = super()._get_info()
        cross, upright = self._task_rewards
        info["reward_crossing"] = cross
        info["reward_upright"] = upright
        info["crossing_progress"] = float(self._progress)
        info["success"] = self.success()
        return info

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Bounding-v0's reset (the noisy paper initial state, or ``options["state"]``) on the task's terrain."""
        self._reset_task(0.0)
        obs, info = super().reset(seed=seed, options=options)
        self._reset_task(float(self.sim.x[IX]))
        info["crossing_progress"] = 0.0
        info["success"] = self.success()
        return obs, info

    def _end_step(self, impulse) -> tuple:
        """The base env's step (its control cost; its speed and healthy terms are off by default) plus the crossing
        and upright terms (class docstring of [`JumpEnv`][JumpEnv])."""
        obs, reward, terminated, truncated, info = super()._end_step(impulse)
        x = self.sim.x
        cross = upright = 0.0
        if not self._invalid:
            span = max(self._target_x - self._x0, 1e-9)
            progress = max(self._progress, min(max((float(x[IX]) - self._x0) / span, 0.0), 1.0))
            cross = self.crossing_reward * (progress - self._progress)
            self._progress = progress
            pitch = float(x[IPITCH])
            up = self._height_above_ground() >= SUCCESS_MIN_HEIGHT
            if self._across() and up and abs(pitch) <= SUCCESS_MAX_PITCH:
                self._hold += 1
                upright = self.upright_reward * math.exp(-(pitch / UPRIGHT_PITCH_SIGMA) ** 2)
            else:
                self._hold = 0
        if terminated:  # a fall takes the crossing reward back
            self._fell = True
            self._hold = 0
            cross = -self._paid
            upright = 0.0
        self._paid += cross
        self._task_rewards = (cross, upright)
        info["reward_crossing"] = cross
        info["reward_upright"] = upright
        info["crossing_progress"] = float(self._progress)
        info["success"] = self.success()
        return obs, float(reward + cross + upright), terminated, truncated, info


class JumpEnv(JumpTask, BoundingEnv):
    r"""Planar MIT Mini Cheetah bounding towards a gap or a box: jump over it (onto it), land and bound on upright.

    ## Description
    The robot, physics, action space, observation layout, info and reset options of
    [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] (``hsddp_gym/Bounding-v0``) on a fixed terrain
    ([`jump_terrain`][hsddp_gym.core.task_constants.jump_terrain]), with the jump task ([`JumpTask`][JumpTask]):
    ``task="gap_jump"`` (``hsddp_gym/GapJump-v0``) puts a 0.3 m gap 0.66 m ahead of the start, ``task="box_jump"``
    (``hsddp_gym/BoxJump-v0``) a 0.1 m high, 3 m long box 0.79 m ahead. The robot starts bounding at 0.9 m/s and is
    rewarded for getting across and then for being upright on the far side. The HS-DDP jumps
    ([`hsddp_gym.planners.motions`][hsddp_gym.planners.motions], ``plan_jump``) do it from two bounding cycles: a 80 ms
    take-off back stance, a 250 ms flight, a landing on the front foot beyond the far edge, then bounding on.

    ## Action space
    ``Box(-1, 1, (4,), float32)``: normalized joint torques, as Bounding-v0 (33 N m a full action, 200 Hz).

    ## Observation space
    ``Box((17,), float32)``, Bounding-v0's layout (no world x: the trunk's height is absolute, above the start's
    ground); the clock (indices 15-16, ``sin, cos 2 pi t / gait_period``) runs once per episode,
    ``gait_period = 2`` s by default (it tells the time since the start, hence roughly how far the obstacle is).

    ## Rewards
    ``reward = crossing_reward * (p_t - p_{t-1}) + upright_reward * [across, up, |pitch| <= 0.6] * exp(-(pitch /
    0.3)^2) - ctrl_cost_weight * ||a||^2`` with ``p_t = max_{s <= t} clip((x_s - x_0) / (x_far + 0.3 - x_0), 0, 1)``
    the largest fraction of the way from the start to 0.3 m past the far edge ``x_far`` (the gap's far rim, the
    box's near edge) (defaults 10, 1, 0.1): the crossing term pays 10 once; the upright term up to 1 per step while
    the trunk is 0.3 m past ``x_far`` with both feet past it, at least 0.15 m above the ground under it. On a fall the
    crossing term takes back everything it paid. Bounding-v0's speed-tracking and healthy terms are off. The terms
    are in ``info``: ``reward_crossing``, ``reward_upright``, ``reward_ctrl`` (and the base's ``reward_forward``,
    ``reward_healthy``, 0 by default).

    ## Starting state
    Bounding-v0's: the paper's initial state (mid back stance, 0.9 m/s) with a seeded noise of scale
    ``reset_noise_scale`` (default 0.01, ``U(-s, s)`` on ``q``, ``s N(0, 1)`` on ``v``); the reset options
    (``state``, ``time``, ``push``) are Bounding-v0's.

    ## Episode end
    ``terminated`` on a fall: Bounding-v0's (the trunk centre leaves ``healthy_z_range`` (0.12, 0.5) m above the
    ground under it, a gap bridged at its rims' level, so dropping into it ends the episode; the pitch leaves
    ``healthy_pitch_range`` (-0.8, 0.8) rad; an invalid state), or a foot 2 cm below the gap's rims while over it.
    ``truncated`` by the registered ``TimeLimit``, 400 control steps (2 s: the approach and the jump take 1 s, then
    about a second bounding on the far side).

    ## Success
    ``info["success"]`` at every step (its value at the last step of an episode is the episode's,
    [`JumpTask.success`][JumpTask.success]): no fall, and for the last 50 control steps (0.25 s) the trunk 0.3 m past
    ``x_far`` with both feet past it, ``|pitch| <= 0.6`` rad and the trunk centre at least 0.15 m above the ground under
    it.

    ## Info
    Bounding-v0's keys (with ``ground_height``, the terrain's) plus ``reward_crossing``, ``reward_upright`` (float),
    ``crossing_progress`` (float, ``p_t``) and ``success`` (bool), the same keys at reset and at every step.

    ## Arguments
    [`JumpTask`][JumpTask]'s and every other argument of [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] but
    ``terrain`` (set by ``task``), all JSON-serializable. Vector env: ``gym.make_vec(ID, num_envs=N)`` builds
    [`JumpVectorEnv`][hsddp_gym.envs.task_vector.JumpVectorEnv] (the physics of all robots in one compiled call,
    bit-identical to N single envs).

    ## Version history
    * v0: initial release.
    """


class MuJoCoJumpEnv(JumpTask, MuJoCoBoundingEnv):
    """``hsddp_gym/GapJumpMuJoCo-v0`` and ``hsddp_gym/BoxJumpMuJoCo-v0``: [`JumpEnv`][JumpEnv]'s task (terrain, reward,
    start, termination, success, arguments) simulated by MuJoCo,
    [`MuJoCoBoundingEnv`][hsddp_gym.envs.mujoco_twin.MuJoCoBoundingEnv] (its contact-model arguments too; needs the
    extra ``mujoco``)."""


__all__ = ["TASKS", "EPISODE_DURATION",
           "GAP_FOOT_DEPTH", "SUCCESS_BEYOND", "SUCCESS_MIN_HEIGHT", "SUCCESS_MAX_PITCH", "HOLD_STEPS",
           "DEFAULT_CROSSING_REWARD", "DEFAULT_UPRIGHT_REWARD", "UPRIGHT_PITCH_SIGMA", "far_edge",
           "JumpTask", "JumpEnv", "MuJoCoJumpEnv"]
