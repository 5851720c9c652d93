"""The plan-tracking tasks (``--task``): the HS-DDP expert of ``hsddp_gym/Backflip-v0``, ``hsddp_gym/GapJump-v0``,
``hsddp_gym/BoxJump-v0`` or a gait transition (``hsddp_gym/StandToBound-v0``, ``hsddp_gym/BoundPronkBound-v0``,
``hsddp_gym/BoundToStop-v0``) in the env and its MuJoCo twin, and BC (and DAgger) from its demonstrations, on unseen
seeds.

Each policy plays ``--episodes`` episodes seeded ``--seed, --seed + 1, ...`` (default 9600-9619 for the backflip,
9650-9669 for the jumps, 9700-9719 for the gait transitions: seeds no dataset uses) of the default task (400 steps =
2 s, 300 for stand-to-bound and bound-to-stop; reset noise 0.01); per episode the return, a fall, the task's own
measures (the backflip: the lowest and final pitch and the lowest trunk clearance; the jumps: the final trunk x and
pitch and the lowest trunk height over the ground; the transitions: the mean and final forward speed, the final
pitch, the lowest trunk height and the pronk stances) and the task's success (``info["success"]`` at the episode's
last step).

    hsddp-gym dataset --env hsddp_gym/GapJump-v0 --policy expert --episodes 24 --seed 1000 --action-noise 0.01 \\
        --out runs/gap_jump_expert24_dart
    hsddp-gym train --algo bc --dataset runs/gap_jump_expert24_dart --seed 0 --out runs/gap_jump_bc_s0
    python experiments/tasks.py --task gap_jump --mujoco --bc runs/gap_jump_bc_s0 ... \\
        --record results/tasks/gap_jump.json --made-with "hsddp-gym dataset ..." "hsddp-gym train ..."

``--bc`` / ``--dagger`` take ``hsddp-gym train --algo bc|dagger --out DIR`` runs (BC's dataset and DAgger's env must
be the task's env), evaluated with their final weights. ``experiments/backflip.py`` is this script with ``--task
backflip``. The tasks, their seeds, measures and success rules are the task registry's (``hsddp_gym.registry``), the
evaluation :mod:`hsddp_gym.benchmarks.tasks`.
"""

from __future__ import annotations

from hsddp_gym.benchmarks.tasks import task_evaluation_main


def main(argv=None) -> int:
    return task_evaluation_main(argv, __doc__)


if __name__ == "__main__":
    raise SystemExit(main())
