"""``hsddp_gym/Backflip-v0``: the Bounding-v0 robot and physics, rewarded for a backflip (see
[`BackflipEnv`][BackflipEnv]).

The task is a mixin, [`BackflipTask`][BackflipTask], on top of an env class of the bounding family, as
[`hsddp_gym.envs.pronking`][hsddp_gym.envs.pronking]'s: [`BackflipEnv`][BackflipEnv] puts it on
[`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] (the exact-LCP simulation),
[`MuJoCoBackflipEnv`][MuJoCoBackflipEnv] on the MuJoCo twin (``hsddp_gym/BackflipMuJoCo-v0``). The physics, the action
and observation layouts and the reset options are the base class's; the task changes the reward (pitch progress to ``-2
pi``, then upright and still on both feet), the healthy set (a fall: the trunk touches the ground, the trunk centre
drops below 0.1 m, or the pitch leaves ``(-2 pi - 1.2, 1.2)`` rad), the start (standing at rest, both feet on the
ground, with a seeded noise), the observation clock's period (the episode, 2 s) and adds a success flag to ``info``
([`backflip_success`][backflip_success]).

Envs do not import the planners (the package's layers), so [`backflip_start_state`][backflip_start_state] repeats the
backflip plan's start (``hsddp_gym.planners.motions.backflip_problem()[0].x0``, standing at rest at 0.26 m);
``tests/test_backflip_env.py`` checks that they agree.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

from hsddp_gym.core.conventions import BACK, FRONT, IPITCH, IVX, IVZ, IZ, NQ
from hsddp_gym.core.task_constants import STAND_HEIGHT
from hsddp_gym.envs.bounding import BoundingEnv
from hsddp_gym.envs.mujoco_twin import MuJoCoBoundingEnv
from hsddp_gym.util.validation import check_in_range, check_positive

FULL_TURN = -2.0 * math.pi
"""The pitch of a completed backflip [rad]: one full turn nose-up (nose-up is negative pitch)."""
EPISODE_DURATION = 2.0
"""Episode length [s]: the flip and its landing (1.05 s in the plan), then a hold; the default observation clock
period."""
DEFAULT_HEALTHY_Z_RANGE = (0.1, 1.0)
"""Healthy trunk-centre heights [m] (the flight's apex is about 0.52 m)."""
DEFAULT_HEALTHY_PITCH_RANGE = (FULL_TURN - 1.2, 1.2)
"""Healthy pitch [rad]: from 1.2 rad nose-down to 1.2 rad past a full turn."""
TRUNK_CONTACT_HEIGHT = 0.05
"""A trunk end (a hip, 0.19 m from the trunk centre) this low [m] means the body (about 10 cm thick) touches the
ground: a fall."""
DEFAULT_ROTATION_REWARD = 20.0
"""Reward for the whole turn, paid as the pitch progresses to ``-2 pi`` (taken back on a fall)."""
DEFAULT_LANDING_REWARD = 1.0
"""Largest landing reward per step: upright at ``-2 pi``, still, both feet on the ground."""
LANDING_PITCH_SIGMA = 0.3
"""Width [rad] of the landing term's pitch factor ``exp(-((pitch + 2 pi) / sigma)^2)``."""
LANDING_SPEED_SIGMA = 0.5
"""Width [m/s] of the landing term's trunk-speed factor."""
LANDING_PITCH_RATE_SIGMA = 2.0
"""Width [rad/s] of the landing term's pitch-rate factor."""
MAX_RESET_NOISE = 0.05
"""Largest ``reset_noise_scale``: the noisy standing start keeps both feet within the legs' reach."""
SUCCESS_PITCH_TOLERANCE = 0.3
"""Success: the pitch within this distance [rad] of ``-2 pi`` at the end (and reached at least that far)."""
SUCCESS_MIN_HEIGHT = 0.15
"""Success: the trunk centre at least this high [m] at the end."""
SUCCESS_MAX_SPEED = 0.3
"""Success: the trunk speed ``sqrt(vx^2 + vz^2)`` at most this [m/s] at the end."""
SUCCESS_MAX_PITCH_RATE = 1.0
"""Success: ``|pitch rate|`` at most this [rad/s] at the end."""


def backflip_start_state(robot, height: float = STAND_HEIGHT) -> np.ndarray:
    """The backflip plan's start ``x (14,)``: standing at rest, both feet on the ground under their hips, trunk at
    ``height`` [m], pitch 0 (joint angles by Newton's method from hips 0.3 pi, knees -0.6 pi, as
    ``hsddp_gym.planners.motions.stand_reference``)."""
    height = check_positive(height, "height")
    q = np.array([0.0, height, 0.0, 0.3 * math.pi, -0.6 * math.pi, 0.3 * math.pi, -0.6 * math.pi])
    hips = robot.hip_positions(q)
    q = robot.place_feet(q, np.array([[hips[f][0], 0.0] for f in (FRONT, BACK)]))
    return np.concatenate([q, np.zeros(NQ)])


def trunk_clearance(x, hip_offset: float) -> float:
    """Height [m] of the lower trunk end (a hip, ``hip_offset`` from the trunk centre along its axis) of the state
    ``x`` (positive pitch is nose-down, so the front hip is at ``z - hip_offset sin(pitch)``)."""
    s = hip_offset * math.sin(float(x[IPITCH]))
    return float(x[IZ]) - abs(s)


def backflip_success(fell: bool, min_pitch: float, final_state, both_feet_down: bool) -> bool:
    """The task's success criterion for one episode: no fall (no termination: the trunk never touched the ground),
    a full turn (the pitch reached ``-2 pi +`` [`SUCCESS_PITCH_TOLERANCE`][SUCCESS_PITCH_TOLERANCE]), and at the end
    upright on both feet and still: pitch within [`SUCCESS_PITCH_TOLERANCE`][SUCCESS_PITCH_TOLERANCE] of ``-2 pi``,
    trunk centre at least [`SUCCESS_MIN_HEIGHT`][SUCCESS_MIN_HEIGHT] high, trunk speed at most
    [`SUCCESS_MAX_SPEED`][SUCCESS_MAX_SPEED], pitch rate at most [`SUCCESS_MAX_PITCH_RATE`][SUCCESS_MAX_PITCH_RATE],
    both contact flags set.

    Args:
        fell: the episode terminated (a fall or an invalid state).
        min_pitch: the lowest pitch of the episode [rad].
        final_state: the last state ``(14,)`` (``info["qpos"]`` and ``info["qvel"]`` concatenated).
        both_feet_down: both contact flags of the last step.
    """
    x = np.asarray(final_state, dtype=np.float64)
    if fell or x.shape != (2 * NQ,) or not np.all(np.isfinite(x)):
        return False
    return bool(float(min_pitch) <= FULL_TURN + SUCCESS_PITCH_TOLERANCE
                and abs(float(x[IPITCH]) - FULL_TURN) <= SUCCESS_PITCH_TOLERANCE
                and float(x[IZ]) >= SUCCESS_MIN_HEIGHT
                and math.hypot(float(x[IVX]), float(x[IVZ])) <= SUCCESS_MAX_SPEED
                and abs(float(x[NQ + IPITCH])) <= SUCCESS_MAX_PITCH_RATE
                and bool(both_feet_down))


class BackflipTask:
    r"""The backflip task, a mixin on an env of the bounding family ([`BackflipEnv`][BackflipEnv],
    [`MuJoCoBackflipEnv`][MuJoCoBackflipEnv]).

    Arguments it adds or changes (every other argument is the base env's):

    | parameter | default | description |
    |---|---|---|
    | ``rotation_reward`` | 20.0 | reward of the whole turn, paid with the pitch's progress to ``-2 pi`` |
    | ``landing_reward`` | 1.0 | largest per-step reward for standing upright and still at ``-2 pi`` |
    | ``trunk_contact_height`` | 0.05 | a trunk end this low [m] is a fall |
    | ``forward_reward_weight`` | 0.0 | the base env's speed-tracking term (off) |
    | ``healthy_reward`` | 0.0 | the base env's per-step healthy reward (off) |
    | ``healthy_z_range`` | (0.1, 1.0) | healthy trunk-centre heights [m] |
    | ``healthy_pitch_range`` | (-2 pi - 1.2, 1.2) | healthy pitch [rad] |
    | ``target_speed`` | 0.0 | the base env's target speed (used only by its speed term) |
    | ``gait_period`` | 2.0 | period of the observation's clock [s]: the episode |
    | ``reset_noise_scale`` | 0.01 | noise of the standing start, at most 0.05 |
    """

    def __init__(self, *, rotation_reward: float = DEFAULT_ROTATION_REWARD,
                 landing_reward: float = DEFAULT_LANDING_REWARD, trunk_contact_height: float = TRUNK_CONTACT_HEIGHT,
                 forward_reward_weight: float = 0.0, healthy_reward: float = 0.0,
                 healthy_z_range=DEFAULT_HEALTHY_Z_RANGE, healthy_pitch_range=DEFAULT_HEALTHY_PITCH_RANGE,
                 target_speed: float = 0.0, gait_period: float = EPISODE_DURATION, reset_noise_scale: float = 0.01,
                 **kwargs) -> None:
        self.rotation_reward = check_positive(rotation_reward, "rotation_reward", allow_zero=True)
        self.landing_reward = check_positive(landing_reward, "landing_reward", allow_zero=True)
        self.trunk_contact_height = check_in_range(trunk_contact_height, 0.0, 0.26, "trunk_contact_height")
        check_in_range(reset_noise_scale, 0.0, MAX_RESET_NOISE, "reset_noise_scale")
        self._reset_task()
        super().__init__(forward_reward_weight=forward_reward_weight, healthy_reward=healthy_reward,
                         healthy_z_range=healthy_z_range, healthy_pitch_range=healthy_pitch_range,
                         target_speed=target_speed, gait_period=gait_period, reset_noise_scale=reset_noise_scale,
                         **kwargs)
        self._hip_offset = float(self.robot.params.hip_offset)
        self.init_state = backflip_start_state(self.robot)
        self.sim.set_state(self.init_state)
        self._update_feet(at_reset=True)

    def _reset_task(self) -> None:
        self._progress = 0.0
        self._min_pitch = 0.0
        self._fell = False
        self._paid = 0.0  # rotation reward paid this episode
        self._task_rewards = (0.0, 0.0)

    # ------------------------------------------------------------------ task state
    @property
    def pitch_progress(self) -> float:
        """The largest fraction of the turn reached so far, ``max_t clip(-pitch / 2 pi, 0, 1)``."""
        return self._progress

    def _healthy(self, valid: bool) -> bool:
        return super()._healthy(valid) and trunk_clearance(self.sim.x, self._hip_offset) > self.trunk_contact_height

    def _success_now(self) -> bool:
        x = self.sim.x
        return backflip_success(self._fell, self._min_pitch, x, bool(self._contact[0] and self._contact[1]))

    def _get_info(self) -> dict:
        info = super()._get_info()
        rot, land = self._task_rewards
        info["reward_rotation"] = rot
        info["reward_landing"] = land
        info["pitch_progress"] = float(self._progress)
        info["trunk_clearance"] = trunk_clearance(self.sim.x, self._hip_offset) if not self._invalid else 0.0
        info["success"] = self._success_now()
        return info

    def _standing_start(self) -> np.ndarray:
        """The noisy standing start: ``q`` plus ``U(-s, s)`` noise, then the joints moved to put both feet on the
        ground where the noise left them ([`place_feet`][hsddp_gym.core.model.CheetahModel.place_feet]); trunk
        velocities ``s N(0, 1)``, joint rates that keep both feet at rest (``J_c v = 0``)."""
        s = self.reset_noise_scale
        x = self.init_state.copy()
        q = x[:NQ] + self.np_random.uniform(low=-s, high=s, size=NQ)
        feet = self.robot.foot_positions(q)
        q = self.robot.place_feet(q, np.array([[feet[f][0], 0.0] for f in (FRONT, BACK)]))
        v = np.zeros(NQ)
        v[:3] = s * self.np_random.standard_normal(3)
        J = np.vstack([self.robot.foot_jacobian(q, f) for f in (FRONT, BACK)])  # (4, 7)
        v[3:] = np.linalg.solve(J[:, 3:], -J[:, :3] @ v[:3])
        return np.concatenate([q, v])

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset to the noisy standing start (`_standing_start`, drawn from ``self.np_random``) or to
        ``options["state"]``; the other options (``time``, ``push``) are the base env's."""
        self._reset_task()
        if options is None or (isinstance(options, dict) and options.get("state") is None):
            gym.Env.reset(self, seed=seed)  # seeds self.np_random
            options = {**(options or {}), "state": self._standing_start()}
            seed = None
        obs, info = super().reset(seed=seed, options=options)
        self._min_pitch = float(self.sim.x[IPITCH])
        self._progress = float(np.clip(-self._min_pitch / (2.0 * math.pi), 0.0, 1.0))
        info["pitch_progress"] = self._progress
        info["success"] = self._success_now()
        return obs, info

    def _end_step(self, impulse) -> tuple:
        """The base env's step (its control cost; its speed and healthy terms are off by default) plus the
        rotation and landing terms (class docstring of [`BackflipEnv`][BackflipEnv])."""
        obs, reward, terminated, truncated, info = super()._end_step(impulse)
        x = self.sim.x
        rot = land = 0.0
        if not self._invalid:
            pitch = float(x[IPITCH])
            self._min_pitch = min(self._min_pitch, pitch)
            progress = max(self._progress, min(max(-pitch / (2.0 * math.pi), 0.0), 1.0))
            rot = self.rotation_reward * (progress - self._progress)
            self._progress = progress
            if self._contact[0] and self._contact[1]:
                d = (pitch - FULL_TURN) / LANDING_PITCH_SIGMA
                speed2 = (float(x[IVX]) ** 2 + float(x[IVZ]) ** 2) / LANDING_SPEED_SIGMA ** 2
                w = float(x[NQ + IPITCH]) / LANDING_PITCH_RATE_SIGMA
                land = self.landing_reward * math.exp(-(d * d) - speed2 - w * w)
        if terminated:  # a fall takes the rotation reward back
            self._fell = True
            rot = -self._paid
            land = 0.0
        self._paid += rot
        self._task_rewards = (rot, land)
        info["reward_rotation"] = rot
        info["reward_landing"] = land
        info["pitch_progress"] = float(self._progress)
        info["success"] = self._success_now()
        return obs, float(reward + rot + land), terminated, truncated, info


class BackflipEnv(BackflipTask, BoundingEnv):
    r"""Planar MIT Mini Cheetah standing on flat ground: do a backflip, land on both feet and stand still.

    ## Description
    The robot, physics, action space, observation layout, info and reset options of
    [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] (``hsddp_gym/Bounding-v0``), with the backflip task
    ([`BackflipTask`][BackflipTask]): the robot starts standing at rest and is rewarded for turning its trunk once
    backwards (pitch from 0 to ``-2 pi``; nose-up is negative pitch) and then for standing upright and still on both
    feet. The HS-DDP backflip ([`hsddp_gym.planners.motions`][hsddp_gym.planners.motions], ``plan_backflip``) does it in
    1.05 s: a 250 ms push on both feet, a 100 ms take-off on the back feet, a 400 ms flight and a 300 ms landing.

    ## Action space
    ``Box(-1, 1, (4,), float32)``: normalized joint torques, as Bounding-v0 (33 N m a full action, 200 Hz).

    ## Observation space
    ``Box((17,), float32)``, Bounding-v0's layout; the pitch (index 1) is not wrapped (a completed flip reads about
    ``-2 pi``); the clock (indices 15-16, ``sin, cos 2 pi t / gait_period``) runs once per episode,
    ``gait_period = 2`` s by default (it tells the time since the start).

    ## Rewards
    ``reward = rotation_reward * (p_t - p_{t-1}) + landing_reward * [both feet down] * exp(-((pitch + 2 pi) / 0.3)^2
    - (vx^2 + vz^2) / 0.5^2 - (pitch_rate / 2)^2) - ctrl_cost_weight * ||a||^2``, with ``p_t = max_{s <= t}
    clip(-pitch_s / 2 pi, 0, 1)`` the largest fraction of the turn so far (defaults 20, 1, 0.1): the rotation term
    pays 20 for the whole turn, once; the landing term up to 1 per step for standing upright at ``-2 pi`` on both
    feet without moving; the torque penalty is Bounding-v0's control cost. On a fall the rotation term takes back
    everything it paid in the episode, so that falling backwards earns nothing. Bounding-v0's
    speed-tracking and healthy terms are off (``forward_reward_weight = healthy_reward = 0``). The terms are in
    ``info``: ``reward_rotation``, ``reward_landing``, ``reward_ctrl`` (and the base's ``reward_forward``,
    ``reward_healthy``, 0 by default).

    ## Starting state
    The backflip plan's start ([`backflip_start_state`][backflip_start_state]): standing at rest, trunk at 0.26 m, pitch
    0, feet under the hips; plus a seeded noise of scale ``s = reset_noise_scale`` (default 0.01, at most 0.05): ``U(-s,
    s)`` on ``q`` after which the joints put both feet back on the ground, ``s N(0, 1)`` on the trunk velocities with
    joint rates that keep the feet at rest. The reset options (``state``, ``time``, ``push``) are Bounding-v0's.

    ## Episode end
    ``terminated`` on a fall: the trunk touches the ground (a trunk end, a hip, below ``trunk_contact_height`` =
    0.05 m), the trunk centre leaves ``healthy_z_range`` (0.1, 1.0) m or the pitch leaves ``healthy_pitch_range``
    ``(-2 pi - 1.2, 1.2)`` rad; or an invalid state (Bounding-v0's rule). ``truncated`` by the registered
    ``TimeLimit``, 400 control steps (2 s: the flip, the landing and about a second standing).

    ## Success
    [`backflip_success`][backflip_success], also ``info["success"]`` at every step (its value at the last step of an
    episode is the episode's): no fall, a full turn, and at the end upright (pitch within 0.3 rad of ``-2 pi``, trunk
    centre at least 0.15 m high) on both feet and still (trunk speed at most 0.3 m/s, pitch rate at most 1 rad/s).

    ## Info
    Bounding-v0's keys plus ``reward_rotation``, ``reward_landing`` (float), ``pitch_progress`` (float, ``p_t``),
    ``trunk_clearance`` (float, the lower trunk end's height [m]) and ``success`` (bool), the same keys at reset
    and at every step.

    ## Arguments
    [`BackflipTask`][BackflipTask]'s and every other argument of [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv],
    all JSON-serializable. Vector env: ``gym.make_vec(ID, num_envs=N)`` builds
    [`BackflipVectorEnv`][hsddp_gym.envs.task_vector.BackflipVectorEnv] (the physics of all robots in one compiled call,
    bit-identical to N single envs).

    ## Version history
    * v0: initial release.
    """


class MuJoCoBackflipEnv(BackflipTask, MuJoCoBoundingEnv):
    """``hsddp_gym/BackflipMuJoCo-v0``: [`BackflipEnv`][BackflipEnv]'s task (reward, start, termination, success,
    arguments) simulated by MuJoCo, [`MuJoCoBoundingEnv`][hsddp_gym.envs.mujoco_twin.MuJoCoBoundingEnv] (its
    contact-model arguments too; needs the extra ``mujoco``)."""


__all__ = ["FULL_TURN", "STAND_HEIGHT", "EPISODE_DURATION", "DEFAULT_HEALTHY_Z_RANGE", "DEFAULT_HEALTHY_PITCH_RANGE",
           "TRUNK_CONTACT_HEIGHT", "DEFAULT_ROTATION_REWARD", "DEFAULT_LANDING_REWARD", "LANDING_PITCH_SIGMA",
           "LANDING_SPEED_SIGMA", "LANDING_PITCH_RATE_SIGMA", "MAX_RESET_NOISE", "SUCCESS_PITCH_TOLERANCE",
           "SUCCESS_MIN_HEIGHT", "SUCCESS_MAX_SPEED", "SUCCESS_MAX_PITCH_RATE", "backflip_start_state",
           "trunk_clearance", "backflip_success", "BackflipTask", "BackflipEnv", "MuJoCoBackflipEnv"]
