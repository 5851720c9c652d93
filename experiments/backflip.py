"""The backflip task (``hsddp_gym/Backflip-v0``): the HS-DDP backflip expert, BC (and DAgger) on unseen seeds, and the
expert in the MuJoCo twin: ``experiments/tasks.py --task backflip`` (the task evaluation of
:mod:`hsddp_gym.benchmarks.tasks`, shared with the jumps).

Each policy plays ``--episodes`` episodes seeded ``--seed, --seed + 1, ...`` (default 9600-9619, seeds no dataset
uses) of the default task (400 steps = 2 s, reset noise 0.01); per episode the return, a fall, the lowest pitch, the
final pitch, the lowest trunk clearance and the task's success (``info["success"]`` at the episode's last step:
:func:`hsddp_gym.envs.backflip.backflip_success`).

    hsddp-gym dataset --env hsddp_gym/Backflip-v0 --policy expert --episodes 24 --seed 1000 --action-noise 0.01 \\
        --out runs/backflip_expert24_dart
    hsddp-gym train --algo bc --dataset runs/backflip_expert24_dart --seed 0 --out runs/backflip_bc_s0
    python experiments/backflip.py --mujoco --bc runs/backflip_bc_s0 ... --record results/tasks/backflip.json \\
        --made-with "hsddp-gym dataset ..." "hsddp-gym train ..."

``--bc`` / ``--dagger`` take ``hsddp-gym train --algo bc|dagger --out DIR`` runs (BC's dataset and DAgger's env must
be Backflip-v0's), evaluated with their final weights.
"""

from __future__ import annotations

from hsddp_gym.benchmarks.tasks import task_evaluation_main


def main(argv=None) -> int:
    return task_evaluation_main(argv, __doc__, task="backflip")


if __name__ == "__main__":
    raise SystemExit(main())
