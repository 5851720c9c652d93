"""hsddp_gym: HS-DDP for the planar MIT Mini Cheetah, and a Gymnasium bounding benchmark.

Importing the package registers the Gymnasium environment of every task of the task registry
([`hsddp_gym.registry.TASKS`][hsddp_gym.registry.TASKS]; entry points imported lazily), so both ``import hsddp_gym;
gym.make("hsddp_gym/Bounding-v0")`` and ``gym.make("hsddp_gym:hsddp_gym/Bounding-v0")`` work;
``gym.make_vec("hsddp_gym/Bounding-v0", num_envs=N, vectorization_mode="vector_entry_point")`` gives the compiled
vector env (``hsddp_gym.envs.vector``). ``hsddp_gym/Terrain-v0`` is Bounding-v0 on a seeded random terrain of steps
and slopes (one per episode). ``hsddp_gym/BoundingMuJoCo-v0`` is the same task simulated by MuJoCo (optional extra
``mujoco``); ``hsddp_gym/BoundingKKT-v0`` the same task simulated by the planner's own hybrid model (pinned feet, KKT
contact dynamics, touchdown reset maps). ``hsddp_gym/Pronking-v0`` is the same robot rewarded for pronking
(``hsddp_gym.envs.pronking``, no compiled vector entry point), ``hsddp_gym/PronkingMuJoCo-v0`` its MuJoCo twin;
``hsddp_gym/Backflip-v0`` rewards a backflip from standing (``hsddp_gym.envs.backflip``),
``hsddp_gym/BackflipMuJoCo-v0`` its MuJoCo twin; ``hsddp_gym/GapJump-v0`` and ``hsddp_gym/BoxJump-v0`` reward
a jump from a bound over a 0.3 m gap and onto a 0.1 m box (``hsddp_gym.envs.jumps``), ``hsddp_gym/GapJumpMuJoCo-v0``
and ``hsddp_gym/BoxJumpMuJoCo-v0`` their MuJoCo twins; ``hsddp_gym/StandToBound-v0``, ``hsddp_gym/BoundPronkBound-v0``
and ``hsddp_gym/BoundToStop-v0`` reward the gait transitions of the HS-DDP transition plans
(``hsddp_gym.envs.transitions``), ``hsddp_gym/StandToBoundMuJoCo-v0``, ``hsddp_gym/BoundPronkBoundMuJoCo-v0`` and
``hsddp_gym/BoundToStopMuJoCo-v0`` their MuJoCo twins.

The env ids and time limits below are read from the registry (pure Python: importing the package loads neither NumPy
nor an env).
"""

from hsddp_gym.core import task_constants as _tc
from hsddp_gym.registry import TASKS as _TASKS
from hsddp_gym.registry import register_envs as _register_envs

__version__ = "0.2.0"

BOUNDING_ENV_ID = _TASKS["bounding"].env_id
BOUNDING_MUJOCO_ENV_ID = _TASKS["bounding"].twins["mujoco"].env_id
"""The same task simulated by MuJoCo (``hsddp_gym.envs.mujoco_twin``; needs the extra ``mujoco``)."""
BOUNDING_KKT_ENV_ID = _TASKS["bounding"].twins["kkt"].env_id
"""The same task simulated by the planner's hybrid model (``hsddp_gym.envs.kkt_twin``)."""
BOUNDING_MAX_EPISODE_STEPS = _tc.BOUNDING_MAX_EPISODE_STEPS
"""1000 control steps = 5 s at the default 200 Hz (about 17 bounding cycles)."""
TERRAIN_ENV_ID = _TASKS["terrain"].env_id
"""Bounding-v0 on a seeded random terrain per episode (``terrain="random_mixed"``: steps up to 3 cm, slopes up to 0.1;
[`hsddp_gym.core.terrain.Terrain.sample`][hsddp_gym.core.terrain.Terrain.sample])."""
PRONKING_ENV_ID = _TASKS["pronking"].env_id
"""The pronking task on Bounding-v0's robot and physics (``hsddp_gym.envs.pronking``)."""
PRONKING_MUJOCO_ENV_ID = _TASKS["pronking"].twin_id
"""The pronking task simulated by MuJoCo (needs the extra ``mujoco``)."""
PRONKING_MAX_EPISODE_STEPS = _tc.PRONKING_MAX_EPISODE_STEPS
"""1000 control steps = 5 s at the default 200 Hz (about 28 pronk cycles)."""
BACKFLIP_ENV_ID = _TASKS["backflip"].env_id
"""The backflip task on Bounding-v0's robot and physics (``hsddp_gym.envs.backflip``)."""
BACKFLIP_MUJOCO_ENV_ID = _TASKS["backflip"].twin_id
"""The backflip task simulated by MuJoCo (needs the extra ``mujoco``)."""
BACKFLIP_MAX_EPISODE_STEPS = _tc.BACKFLIP_MAX_EPISODE_STEPS
"""400 control steps = 2 s at the default 200 Hz (the flip and its landing take 1.05 s, then a hold)."""
GAP_JUMP_ENV_ID = _TASKS["gap_jump"].env_id
"""The jump over a 0.3 m gap on Bounding-v0's robot and physics (``hsddp_gym.envs.jumps``, ``task="gap_jump"``)."""
BOX_JUMP_ENV_ID = _TASKS["box_jump"].env_id
"""The jump onto a 0.1 m box (``hsddp_gym.envs.jumps``, ``task="box_jump"``)."""
GAP_JUMP_MUJOCO_ENV_ID = _TASKS["gap_jump"].twin_id
"""The gap jump simulated by MuJoCo (needs the extra ``mujoco``)."""
BOX_JUMP_MUJOCO_ENV_ID = _TASKS["box_jump"].twin_id
"""The box jump simulated by MuJoCo (needs the extra ``mujoco``)."""
JUMP_MAX_EPISODE_STEPS = _tc.JUMP_MAX_EPISODE_STEPS
"""400 control steps = 2 s at the default 200 Hz (the approach and the jump take 1 s, then bounding on)."""
TRANSITION_ENV_IDS = {name: _TASKS[name].env_id for name in _tc.TRANSITIONS}
"""The gait-transition tasks' envs (``hsddp_gym.envs.transitions``, ``task=`` the key)."""
TRANSITION_MUJOCO_ENV_IDS = {name: _TASKS[name].twin_id for name in _tc.TRANSITIONS}
"""Their MuJoCo twins (need the extra ``mujoco``)."""
TRANSITION_MAX_EPISODE_STEPS = dict(_tc.TRANSITION_MAX_EPISODE_STEPS)
"""Control steps per episode (1.5 s, 2 s, 1.5 s at 200 Hz: the plan and at least 0.4 s more)."""

_register_envs()
