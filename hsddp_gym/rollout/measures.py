"""The tasks' per-episode measures (``Task.measures`` of the task registry) and the observer that takes them.

A [`Measures`][Measures] says what an episode of a task keeps beyond its return, length and fall: an accumulator started
from the reset's ``info`` and updated with every step's, the episode's values from it and the last step's ``info``,
its success, the measures of a row of episodes and their printed form. [`TaskEpisodes`][TaskEpisodes] is the episode
loop's observer that applies them ([`hsddp_gym.rollout.episodes.run_episode`][hsddp_gym.rollout.episodes.run_episode]).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np


def _info_success(acc, info, fell: bool) -> bool:
    return bool(info["success"])


@dataclasses.dataclass(frozen=True)
class Measures:
    """The per-episode measures of a task.

    Attributes:
        start: ``(env, info at reset) -> accumulator`` (a dict).
        update: ``(acc, info) -> None``, at every step.
        finish: ``(acc, info at the last step) -> the episode's measures`` (a dict).
        summarize: ``episodes -> the row's measures`` (a dict).
        describe: ``row -> the printed measures`` (str).
        per_episode: the per-episode values a record keeps (None: all of them).
        success: ``(acc, info at the last step, fell) -> bool`` (default: ``info["success"]``, the env's rule).
        return_digits: the episode's return rounded to these decimals (None: as summed).
    """

    start: Callable
    update: Callable
    finish: Callable
    summarize: Callable
    describe: Callable
    per_episode: tuple | None = None
    success: Callable = _info_success
    return_digits: int | None = 3


class TaskEpisodes:
    """Observer of the episode loop: per episode, ``{"seed", "return", "length", "fell", **measures, "success"}``
    ([`episode`][episode], after [`run_episode`][hsddp_gym.rollout.episodes.run_episode])."""

    def __init__(self, measures: Measures) -> None:
        self.measures = measures
        self.acc, self.ret, self.steps, self.info, self.fell = None, 0.0, 0, None, False

    def on_reset(self, env, obs, info) -> None:
        self.acc, self.ret, self.steps, self.info, self.fell = self.measures.start(env, info), 0.0, 0, info, False

    def on_step(self, env, action, obs, reward, terminated, truncated, info) -> None:
        self.ret += reward
        self.steps += 1
        self.measures.update(self.acc, info)
        self.info, self.fell = info, bool(terminated)

    def episode(self, seed: int) -> dict:
        """The last episode's values (seeded ``seed``)."""
        m = self.measures
        ret = round(float(self.ret), m.return_digits) if m.return_digits is not None else float(self.ret)
        return {"seed": int(seed), "return": ret, "length": self.steps, "fell": self.fell,
                **m.finish(self.acc, self.info), "success": m.success(self.acc, self.info, self.fell)}


# ------------------------------------------------------------------ the backflip
def _flip_start(env, info) -> dict:
    return {"min_pitch": float(info["qpos"][2]), "clearance": float(info["trunk_clearance"])}


def _flip_update(acc, info) -> None:
    acc["min_pitch"] = min(acc["min_pitch"], float(info["qpos"][2]))
    acc["clearance"] = min(acc["clearance"], float(info["trunk_clearance"]))


def _flip_finish(acc, info) -> dict:
    return {"min_pitch": round(acc["min_pitch"], 4), "final_pitch": round(float(info["qpos"][2]), 4),
            "min_trunk_clearance": round(acc["clearance"], 4)}


def _flip_summary(eps) -> dict:
    return {"mean_final_pitch": float(np.mean([e["final_pitch"] for e in eps])),
            "mean_min_pitch": float(np.mean([e["min_pitch"] for e in eps])),
            "min_trunk_clearance": float(np.min([e["min_trunk_clearance"] for e in eps]))}


FLIP = Measures(start=_flip_start, update=_flip_update, finish=_flip_finish, summarize=_flip_summary,
                describe=lambda r: (f"final pitch {r['mean_final_pitch']:.3f}  min trunk clearance "
                                    f"{r['min_trunk_clearance']:.3f} m"),
                per_episode=("seed", "return", "length", "fell", "success", "final_pitch"))
"""The backflip's: the lowest and final pitch, the lowest trunk clearance."""


# ------------------------------------------------------------------ the jumps
def _height(info) -> float:
    return float(info["qpos"][1]) - float(info["ground_height"])


def _jump_start(env, info) -> dict:
    return {"min_height": _height(info)}


def _jump_update(acc, info) -> None:
    if not info.get("invalid_state", False):
        acc["min_height"] = min(acc["min_height"], _height(info))


def _jump_finish(acc, info) -> dict:
    return {"final_x": round(float(info["x_position"]), 4), "final_pitch": round(float(info["qpos"][2]), 4),
            "min_trunk_height": round(acc["min_height"], 4)}


def _jump_summary(eps) -> dict:
    return {"mean_final_x": float(np.mean([e["final_x"] for e in eps])),
            "mean_final_pitch": float(np.mean([e["final_pitch"] for e in eps])),
            "min_trunk_height": float(np.min([e["min_trunk_height"] for e in eps]))}


JUMP = Measures(start=_jump_start, update=_jump_update, finish=_jump_finish, summarize=_jump_summary,
                describe=lambda r: (f"final x {r['mean_final_x']:.2f} m  lowest trunk height "
                                    f"{r['min_trunk_height']:.3f} m"),
                per_episode=("seed", "return", "length", "fell", "success", "final_x"))
"""The jumps': the final trunk x and pitch, the lowest trunk height over the ground."""


# ------------------------------------------------------------------ the gait transitions
def _gait_start(env, info) -> dict:
    return {"min_height": float(info["qpos"][1]), "x0": float(info["x_position"]), "t0": float(info["time"])}


def _gait_update(acc, info) -> None:
    if not info.get("invalid_state", False):
        acc["min_height"] = min(acc["min_height"], float(info["qpos"][1]))


def _gait_finish(acc, info) -> dict:
    t = max(float(info["time"]) - acc["t0"], 1e-9)
    return {"mean_speed": round((float(info["x_position"]) - acc["x0"]) / t, 4),
            "final_speed": round(float(info["qvel"][0]), 4), "final_pitch": round(float(info["qpos"][2]), 4),
            "min_trunk_height": round(acc["min_height"], 4), "pronk_stances": int(info["pronk_stances"])}


def _gait_summary(eps) -> dict:
    return {"mean_final_speed": float(np.mean([e["final_speed"] for e in eps])),
            "mean_speed": float(np.mean([e["mean_speed"] for e in eps])),
            "min_trunk_height": float(np.min([e["min_trunk_height"] for e in eps]))}


GAIT = Measures(start=_gait_start, update=_gait_update, finish=_gait_finish, summarize=_gait_summary,
                describe=lambda r: (f"final speed {r['mean_final_speed']:.2f} m/s  lowest trunk height "
                                    f"{r['min_trunk_height']:.3f} m"),
                per_episode=("seed", "return", "length", "fell", "success", "final_speed"))
"""The gait transitions': the mean and final forward speed, the final pitch, the lowest trunk height, the pronk
stances."""


# ------------------------------------------------------------------ the pronk
def _pronk_start(env, info) -> dict:
    return {"speeds": [], "contacts": [], "target": float(env.unwrapped.target_speed)}


def _pronk_update(acc, info) -> None:
    acc["speeds"].append(info["x_velocity"])
    acc["contacts"].append(info["contact"])


def _pronk_finish(acc, info) -> dict:
    from hsddp_gym.envs.pronking import contact_match_fraction

    acc["mean_speed"], acc["match_fraction"] = float(np.mean(acc["speeds"])), contact_match_fraction(acc["contacts"])
    return {"mean_speed": acc["mean_speed"], "match_fraction": acc["match_fraction"]}


def _pronk_success(acc, info, fell: bool) -> bool:
    from hsddp_gym.envs.pronking import pronking_success

    return pronking_success(fell, acc["mean_speed"], acc["match_fraction"], acc["target"])


def _pronk_summary(eps) -> dict:
    return {"mean_speed": float(np.mean([e["mean_speed"] for e in eps])),
            "mean_match_fraction": float(np.mean([e["match_fraction"] for e in eps])),
            "min_match_fraction": float(np.min([e["match_fraction"] for e in eps]))}


PRONK = Measures(start=_pronk_start, update=_pronk_update, finish=_pronk_finish, summarize=_pronk_summary,
                 describe=lambda r: (f"speed {r['mean_speed']:.3f}  match {r['mean_match_fraction']:.3f} (min "
                                     f"{r['min_match_fraction']:.3f})"),
                 success=_pronk_success, return_digits=None)
"""The pronk's: the mean forward speed and the fraction of control steps with matching contact flags; success by
[`hsddp_gym.envs.pronking.pronking_success`][hsddp_gym.envs.pronking.pronking_success]."""
