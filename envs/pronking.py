"""``hsddp_gym/Pronking-v0``: the Bounding-v0 robot and physics, rewarded for pronking (see
[`PronkingEnv`][PronkingEnv]).

The task is a mixin, [`PronkingTask`][PronkingTask], on top of an env class of the bounding family:
[`PronkingEnv`][PronkingEnv] puts it on [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] (the exact-LCP simulation),
[`MuJoCoPronkingEnv`][MuJoCoPronkingEnv] on the MuJoCo twin (``hsddp_gym/PronkingMuJoCo-v0``). The physics, the action
and observation layouts, the termination and the reset options are the base class's, untouched; the task changes four
things: the reward (a contact-matching term), the observation clock's period (the pronk's cycle), the initial state (the
pronk plan's start) and the range of target speeds. [`pronking_success`][pronking_success] is its success criterion.

Envs do not import the planners (the package's layers), so the pronk's constants below repeat those of
[`hsddp_gym.planners.motions`][hsddp_gym.planners.motions] (``PRONK_DURATIONS``, ``PRONK_HEIGHT``, ``SPEED_RANGE``) and
[`pronk_start_state`][pronk_start_state] repeats its start state (``pronk_problem(...)[0].x0``);
``tests/test_pronking_env.py`` checks that they agree.
"""

from __future__ import annotations

import math

import numpy as np

from hsddp_gym.core.conventions import BACK, FRONT, NQ
from hsddp_gym.core.task_constants import PRONK_DURATIONS, PRONK_HEIGHT
from hsddp_gym.core.task_constants import SPEED_RANGE as PRONK_SPEED_RANGE
from hsddp_gym.envs.bounding import BoundingEnv, _check_bool
from hsddp_gym.envs.mujoco_twin import MuJoCoBoundingEnv
from hsddp_gym.util.validation import check_positive

PRONK_PERIOD = sum(PRONK_DURATIONS)
"""The pronk's cycle, 0.18 s: the default period of the observation's gait clock."""
DEFAULT_CONTACT_MATCH_REWARD = 0.5
"""Weight of the contact-matching term: paid on a healthy step whose two contact flags are equal."""
SUCCESS_SPEED_TOLERANCE = 0.2
"""Success: the episode's mean forward speed within this fraction of the target speed."""
SUCCESS_MATCH_FRACTION = 0.8
"""Success: at least this fraction of the control steps with matching contact flags."""


def pronk_start_state(robot, speed: float, height: float = PRONK_HEIGHT) -> np.ndarray:
    """The pronk plan's start ``x (14,)``: mid double stance, both feet on the ground under their hips, trunk at
    ``height`` [m], pitch 0, moving forward at ``speed`` [m/s] with the joint rates that keep both feet at rest
    (``J_c v = 0``). The joint angles by Newton's method from hips 0.3 pi, knees -0.6 pi (as
    ``hsddp_gym.planners.motions.leg_posture``)."""
    q = np.array([0.0, float(height), 0.0, 0.3 * math.pi, -0.6 * math.pi, 0.3 * math.pi, -0.6 * math.pi])
    hips = robot.hip_positions(q)
    q = robot.place_feet(q, np.array([[hips[f][0], 0.0] for f in (FRONT, BACK)]))
    v = np.zeros(NQ)
    v[0] = float(speed)
    J = np.vstack([robot.foot_jacobian(q, f) for f in (FRONT, BACK)])  # (4, 7)
    v[3:] = np.linalg.solve(J[:, 3:], -J[:, :3] @ v[:3])
    return np.concatenate([q, v])


def contact_match_fraction(contacts) -> float:
    """The fraction of rows of ``contacts (T, 2)`` (the per-step ``info["contact"]`` flags) whose two flags are
    equal (both feet on the ground or both in the air)."""
    c = np.asarray(contacts, dtype=bool).reshape(-1, 2)
    return float(np.mean(c[:, 0] == c[:, 1])) if len(c) else 0.0


def pronking_success(fell: bool, mean_speed: float, match_fraction: float, target_speed: float) -> bool:
    """The task's success criterion for one episode: no fall (no termination), the mean forward speed within
    [`SUCCESS_SPEED_TOLERANCE`][SUCCESS_SPEED_TOLERANCE] (20 %) of ``target_speed`` and at least
    [`SUCCESS_MATCH_FRACTION`][SUCCESS_MATCH_FRACTION] (80 %) of the control steps with matching contact flags
    ([`contact_match_fraction`][contact_match_fraction])."""
    return (not fell) and abs(float(mean_speed) - float(target_speed)) <= SUCCESS_SPEED_TOLERANCE * abs(
        float(target_speed)) and float(match_fraction) >= SUCCESS_MATCH_FRACTION


class PronkingTask:
    r"""The pronking task, a mixin on an env of the bounding family ([`PronkingEnv`][PronkingEnv],
    [`MuJoCoPronkingEnv`][MuJoCoPronkingEnv]).

    Arguments it adds or changes (every other argument is the base env's):

    | parameter | default | description |
    |---|---|---|
    | ``target_speed`` | 1.0 | desired forward speed [m/s], in [0.5, 1.5] ([`PRONK_SPEED_RANGE`][PRONK_SPEED_RANGE]) |
    | ``gait_period`` | 0.18 | period of the observation's clock [s]: the pronk's cycle ([`PRONK_PERIOD`][PRONK_PERIOD])
    |
    | ``contact_match_reward`` | 0.5 | weight of the contact-matching term |
    | ``start_at_pronk`` | True | start at the pronk plan's start ([`pronk_start_state`][pronk_start_state]); False: the
    base env's | """

    def __init__(self, *, target_speed: float = 1.0, gait_period: float = PRONK_PERIOD,
                 contact_match_reward: float = DEFAULT_CONTACT_MATCH_REWARD, start_at_pronk: bool = True,
                 **kwargs) -> None:
        lo, hi = PRONK_SPEED_RANGE
        if isinstance(target_speed, bool) or not isinstance(target_speed, (int, float, np.floating, np.integer)) \
                or not lo <= float(target_speed) <= hi:
            raise ValueError(f"target_speed must be a number in [{lo}, {hi}] m/s (the speeds the pronk is planned "
                             f"for), got {target_speed!r}")
        self.contact_match_reward = check_positive(contact_match_reward, "contact_match_reward", allow_zero=True)
        self.start_at_pronk = _check_bool(start_at_pronk, "start_at_pronk")
        self._match_reward = 0.0
        super().__init__(target_speed=float(target_speed), gait_period=gait_period, **kwargs)
        if self.start_at_pronk:
            self.init_state = pronk_start_state(self.robot, self.target_speed)
            self.sim.set_state(self.init_state)
            self._update_feet(at_reset=True)

    @property
    def contact_match(self) -> bool:
        """Both contact flags equal (both feet on the ground, or both in the air)."""
        return bool(self._contact[0] == self._contact[1])

    def _get_info(self) -> dict:
        info = super()._get_info()
        info["reward_contact_match"] = self._match_reward
        info["contact_match"] = self.contact_match
        return info

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """The base env's reset (same options); from the pronk plan's start by default."""
        self._match_reward = 0.0
        return super().reset(seed=seed, options=options)

    def _begin_step(self, action) -> None:
        self._match_reward = 0.0
        super()._begin_step(action)

    def _end_step(self, impulse) -> tuple:
        """The base env's step plus ``contact_match_reward`` on a healthy step whose contact flags are equal."""
        obs, reward, terminated, truncated, info = super()._end_step(impulse)
        if self.is_healthy:
            self._match_reward = self.contact_match_reward if self.contact_match else 0.0
        info["reward_contact_match"] = self._match_reward
        return obs, float(reward + self._match_reward), terminated, truncated, info


class PronkingEnv(PronkingTask, BoundingEnv):
    r"""Planar MIT Mini Cheetah on flat ground: pronk (both legs together) forward at a target speed.

    ## Description
    The robot, physics, action space, observation layout, termination, info and reset options of
    [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] (``hsddp_gym/Bounding-v0``), with the pronking task
    ([`PronkingTask`][PronkingTask]): a reward for keeping both feet in the same contact state, the observation's clock
    at the pronk's cycle, and a start in the pronk plan's initial state. A pronk is a double stance and a flight
    repeated ([`hsddp_gym.planners.motions`][hsddp_gym.planners.motions]: 100 ms and 80 ms, 0.18 s a cycle), both feet
    landing together.

    ## Action space
    ``Box(-1, 1, (4,), float32)``: normalized joint torques, as Bounding-v0 (33 N m a full action, 200 Hz).

    ## Observation space
    ``Box((17,), float32)``, Bounding-v0's layout; the gait clock (indices 15-16, ``sin, cos 2 pi t /
    gait_period``) runs at the pronk's cycle, ``gait_period = 0.18`` s by default.

    ## Rewards
    ``reward = forward_reward_weight * exp(-((v - target_speed) / tracking_sigma)^2) - ctrl_cost_weight * ||a||^2
    + healthy_reward * is_healthy + contact_match_reward * is_healthy * [contact_front == contact_back]``,
    Bounding-v0's terms (defaults 1, 0.1, 0.5, ``tracking_sigma`` 0.5 m/s) plus the contact-matching term
    (default 0.5), paid on a healthy step when both feet are on the ground or both in the air (the contact flags
    of the observation: the ground pushed the foot during the step's last 1 ms). At most 2 per step. The terms are
    in ``info``: ``reward_forward``, ``reward_ctrl``, ``reward_healthy``, ``reward_contact_match``.

    ## Starting state
    The pronk plan's start ([`pronk_start_state`][pronk_start_state], ``plan_pronk``'s ``X[0]`` at ``target_speed``):
    mid double stance, feet under the hips, trunk at 0.26 m, pitch 0, moving at ``target_speed``; plus Bounding-v0's
    reset noise (``reset_noise_scale``, default 0.01). ``start_at_pronk=False`` keeps Bounding-v0's start. The reset
    options (``state``, ``time``, ``push``) are Bounding-v0's.

    ## Episode end
    Bounding-v0's: ``terminated`` on a fall (trunk height outside (0.12, 0.5) m, pitch outside ±0.8 rad) or an
    invalid state; ``truncated`` by the registered ``TimeLimit``, 1000 control steps (5 s, about 28 pronk cycles).

    ## Success
    [`pronking_success`][pronking_success]: no fall, the mean forward speed within 20 % of ``target_speed`` and at least
    80 % of the control steps with matching contact flags.

    ## Info
    Bounding-v0's keys plus ``reward_contact_match`` (float) and ``contact_match`` (bool, the two flags equal), the
    same keys at reset and at every step.

    ## Arguments
    [`PronkingTask`][PronkingTask]'s (``target_speed`` in [0.5, 1.5] m/s, ``gait_period`` 0.18 s,
    ``contact_match_reward`` 0.5, ``start_at_pronk`` True) and every other argument of
    [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv], all JSON-serializable. Vector env:
    ``gym.make_vec(ID, num_envs=N)`` builds [`PronkingVectorEnv`][hsddp_gym.envs.task_vector.PronkingVectorEnv] (the
    physics of all robots in one compiled call, bit-identical to N single envs).

    ## Version history
    * v0: initial release.
    """


class MuJoCoPronkingEnv(PronkingTask, MuJoCoBoundingEnv):
    """``hsddp_gym/PronkingMuJoCo-v0``: [`PronkingEnv`][PronkingEnv]'s task (reward, clock, start, arguments) simulated
    by MuJoCo, [`MuJoCoBoundingEnv`][hsddp_gym.envs.mujoco_twin.MuJoCoBoundingEnv] (its contact-model arguments too;
    needs the extra ``mujoco``)."""


__all__ = ["PRONK_DURATIONS", "PRONK_PERIOD", "PRONK_HEIGHT", "PRONK_SPEED_RANGE", "DEFAULT_CONTACT_MATCH_REWARD",
           "SUCCESS_SPEED_TOLERANCE", "SUCCESS_MATCH_FRACTION", "pronk_start_state", "contact_match_fraction",
           "pronking_success", "PronkingTask", "PronkingEnv", "MuJoCoPronkingEnv"]
