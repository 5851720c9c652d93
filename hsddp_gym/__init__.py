"""hsddp_gym: HS-DDP for the planar MIT Mini Cheetah, and a Gymnasium bounding benchmark.

Importing the package registers the Gymnasium environment ``hsddp_gym/Bounding-v0`` (entry point
``hsddp_gym.envs.bounding:BoundingEnv``, imported lazily), so both ``import hsddp_gym;
gym.make("hsddp_gym/Bounding-v0")``
and ``gym.make("hsddp_gym:hsddp_gym/Bounding-v0")`` work; ``gym.make_vec("hsddp_gym/Bounding-v0", num_envs=N,
vectorization_mode="vector_entry_point")`` gives the compiled vector env (``hsddp_gym.envs.vector``).
``hsddp_gym/Terrain-v0`` is Bounding-v0 on a seeded random terrain of steps and slopes (one per episode).
``hsddp_gym/BoundingMuJoCo-v0`` is the same task simulated by MuJoCo (optional extra ``mujoco``);
``hsddp_gym/BoundingKKT-v0`` the same task simulated by the planner's own hybrid model (pinned feet, KKT contact
dynamics, touchdown reset maps). ``hsddp_gym/Pronking-v0`` is the same robot rewarded for pronking
(``hsddp_gym.envs.pronking``, no compiled vector entry point), ``hsddp_gym/PronkingMuJoCo-v0`` its MuJoCo twin;
``hsddp_gym/Backflip-v0`` rewards a backflip from standing (``hsddp_gym.envs.backflip``),
``hsddp_gym/BackflipMuJoCo-v0`` its MuJoCo twin; ``hsddp_gym/GapJump-v0`` and ``hsddp_gym/BoxJump-v0`` reward
a jump from a bound over a 0.3 m gap and onto a 0.1 m box (``hsddp_gym.envs.jumps``), ``hsddp_gym/GapJumpMuJoCo-v0``
and ``hsddp_gym/BoxJumpMuJoCo-v0`` their MuJoCo twins; ``hsddp_gym/StandToBound-v0``, ``hsddp_gym/BoundPronkBound-v0``
and ``hsddp_gym/BoundToStop-v0`` reward the gait transitions of the HS-DDP transition plans
(``hsddp_gym.envs.transitions``), ``hsddp_gym/StandToBoundMuJoCo-v0``, ``hsddp_gym/BoundPronkBoundMuJoCo-v0`` and
``hsddp_gym/BoundToStopMuJoCo-v0`` their MuJoCo twins.
"""

__version__ = "0.2.0"

BOUNDING_ENV_ID = "hsddp_gym/Bounding-v0"
BOUNDING_MUJOCO_ENV_ID = "hsddp_gym/BoundingMuJoCo-v0"
"""The same task simulated by MuJoCo (``hsddp_gym.envs.mujoco_twin``; needs the extra ``mujoco``)."""
BOUNDING_KKT_ENV_ID = "hsddp_gym/BoundingKKT-v0"
"""The same task simulated by the planner's hybrid model (``hsddp_gym.envs.kkt_twin``)."""
BOUNDING_MAX_EPISODE_STEPS = 1000
"""1000 control steps = 5 s at the default 200 Hz (about 17 bounding cycles)."""
TERRAIN_ENV_ID = "hsddp_gym/Terrain-v0"
"""Bounding-v0 on a seeded random terrain per episode (``terrain="random_mixed"``: steps up to 3 cm, slopes up to 0.1;
:meth:`hsddp_gym.core.terrain.Terrain.sample`)."""
PRONKING_ENV_ID = "hsddp_gym/Pronking-v0"
"""The pronking task on Bounding-v0's robot and physics (``hsddp_gym.envs.pronking``)."""
PRONKING_MUJOCO_ENV_ID = "hsddp_gym/PronkingMuJoCo-v0"
"""The pronking task simulated by MuJoCo (needs the extra ``mujoco``)."""
PRONKING_MAX_EPISODE_STEPS = 1000
"""1000 control steps = 5 s at the default 200 Hz (about 28 pronk cycles)."""
BACKFLIP_ENV_ID = "hsddp_gym/Backflip-v0"
"""The backflip task on Bounding-v0's robot and physics (``hsddp_gym.envs.backflip``)."""
BACKFLIP_MUJOCO_ENV_ID = "hsddp_gym/BackflipMuJoCo-v0"
"""The backflip task simulated by MuJoCo (needs the extra ``mujoco``)."""
BACKFLIP_MAX_EPISODE_STEPS = 400
"""400 control steps = 2 s at the default 200 Hz (the flip and its landing take 1.05 s, then a hold)."""

GAP_JUMP_ENV_ID = "hsddp_gym/GapJump-v0"
"""The jump over a 0.3 m gap on Bounding-v0's robot and physics (``hsddp_gym.envs.jumps``, ``task="gap_jump"``)."""
BOX_JUMP_ENV_ID = "hsddp_gym/BoxJump-v0"
"""The jump onto a 0.1 m box (``hsddp_gym.envs.jumps``, ``task="box_jump"``)."""
GAP_JUMP_MUJOCO_ENV_ID = "hsddp_gym/GapJumpMuJoCo-v0"
"""The gap jump simulated by MuJoCo (needs the extra ``mujoco``)."""
BOX_JUMP_MUJOCO_ENV_ID = "hsddp_gym/BoxJumpMuJoCo-v0"
"""The box jump simulated by MuJoCo (needs the extra ``mujoco``)."""
JUMP_MAX_EPISODE_STEPS = 400
"""400 control steps = 2 s at the default 200 Hz (the approach and the jump take 1 s, then bounding on)."""

TRANSITION_ENV_IDS = {"stand_to_bound": "hsddp_gym/StandToBound-v0",
                      "bound_pronk_bound": "hsddp_gym/BoundPronkBound-v0", "bound_to_stop": "hsddp_gym/BoundToStop-v0"}
"""The gait-transition tasks' envs (``hsddp_gym.envs.transitions``, ``task=`` the key)."""
TRANSITION_MUJOCO_ENV_IDS = {task: env_id.replace("-v0", "MuJoCo-v0") for task, env_id in TRANSITION_ENV_IDS.items()}
"""Their MuJoCo twins (need the extra ``mujoco``)."""
TRANSITION_MAX_EPISODE_STEPS = {"stand_to_bound": 300, "bound_pronk_bound": 400, "bound_to_stop": 300}
"""Control steps per episode (1.5 s, 2 s, 1.5 s at 200 Hz: the plan and at least 0.4 s more;
``hsddp_gym.envs.transitions.MAX_EPISODE_STEPS``)."""


def _register_envs() -> None:
    import gymnasium as gym

    if BOUNDING_ENV_ID not in gym.registry:
        gym.register(id=BOUNDING_ENV_ID, entry_point="hsddp_gym.envs.bounding:BoundingEnv",
                     vector_entry_point="hsddp_gym.envs.vector:BoundingVectorEnv",
                     max_episode_steps=BOUNDING_MAX_EPISODE_STEPS)
    if TERRAIN_ENV_ID not in gym.registry:  # no vector entry point: the compiled vector env is flat-ground only
        gym.register(id=TERRAIN_ENV_ID, entry_point="hsddp_gym.envs.bounding:BoundingEnv",
                     kwargs={"terrain": "random_mixed"}, max_episode_steps=BOUNDING_MAX_EPISODE_STEPS)
    if BOUNDING_MUJOCO_ENV_ID not in gym.registry:
        gym.register(id=BOUNDING_MUJOCO_ENV_ID, entry_point="hsddp_gym.envs.mujoco_twin:MuJoCoBoundingEnv",
                     max_episode_steps=BOUNDING_MAX_EPISODE_STEPS)
    if BOUNDING_KKT_ENV_ID not in gym.registry:
        gym.register(id=BOUNDING_KKT_ENV_ID, entry_point="hsddp_gym.envs.kkt_twin:KKTBoundingEnv",
                     max_episode_steps=BOUNDING_MAX_EPISODE_STEPS)
    if PRONKING_ENV_ID not in gym.registry:  # no vector entry point: the compiled kernel computes the bound's reward
        gym.register(id=PRONKING_ENV_ID, entry_point="hsddp_gym.envs.pronking:PronkingEnv",
                     max_episode_steps=PRONKING_MAX_EPISODE_STEPS)
    if PRONKING_MUJOCO_ENV_ID not in gym.registry:
        gym.register(id=PRONKING_MUJOCO_ENV_ID, entry_point="hsddp_gym.envs.pronking:MuJoCoPronkingEnv",
                     max_episode_steps=PRONKING_MAX_EPISODE_STEPS)
    if BACKFLIP_ENV_ID not in gym.registry:
        gym.register(id=BACKFLIP_ENV_ID, entry_point="hsddp_gym.envs.backflip:BackflipEnv",
                     max_episode_steps=BACKFLIP_MAX_EPISODE_STEPS)
    if BACKFLIP_MUJOCO_ENV_ID not in gym.registry:
        gym.register(id=BACKFLIP_MUJOCO_ENV_ID, entry_point="hsddp_gym.envs.backflip:MuJoCoBackflipEnv",
                     max_episode_steps=BACKFLIP_MAX_EPISODE_STEPS)
    for env_id, entry, task in ((GAP_JUMP_ENV_ID, "JumpEnv", "gap_jump"), (BOX_JUMP_ENV_ID, "JumpEnv", "box_jump"),
                                (GAP_JUMP_MUJOCO_ENV_ID, "MuJoCoJumpEnv", "gap_jump"),
                                (BOX_JUMP_MUJOCO_ENV_ID, "MuJoCoJumpEnv", "box_jump")):
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=f"hsddp_gym.envs.jumps:{entry}", kwargs={"task": task},
                         max_episode_steps=JUMP_MAX_EPISODE_STEPS)
    for task, env_id in TRANSITION_ENV_IDS.items():
        for eid, entry in ((env_id, "TransitionEnv"), (TRANSITION_MUJOCO_ENV_IDS[task], "MuJoCoTransitionEnv")):
            if eid not in gym.registry:
                gym.register(id=eid, entry_point=f"hsddp_gym.envs.transitions:{entry}", kwargs={"task": task},
                             max_episode_steps=TRANSITION_MAX_EPISODE_STEPS[task])


_register_envs()
