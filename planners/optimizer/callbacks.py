"""Solver callbacks: called with every [`IterationRecord`][hsddp_gym.planners.optimizer.solution.IterationRecord] as it
is logged."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import TextIO

from hsddp_gym.planners.optimizer.solution import IterationRecord

Callback = Callable[[IterationRecord], None]


class VerbosePrinter:
    """Prints one table row per record (the CLI's progress display).

    Args:
        stream: where to print (default stderr). every: print every n-th DDP iteration (AL events always).
    """

    HEADER = (f"{'AL':>3} {'DDP':>4} {'objective':>12} {'cost':>11} {'sum g^2':>10} {'tau viol':>9} "
              f"{'min fz':>8} {'fric viol':>9} {'step':>7} {'mu':>8} {'time s':>7}  event")

    def __init__(self, stream: TextIO | None = None, every: int = 1) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.every = max(1, int(every))
        self._printed_header = False

    def __call__(self, r: IterationRecord) -> None:
        if r.event == "ddp" and r.ddp_iteration % self.every:
            return
        if not self._printed_header:
            print(self.HEADER, file=self.stream)
            self._printed_header = True
        print(f"{r.al_iteration:>3d} {r.ddp_iteration:>4d} {r.objective:>12.5g} {r.cost:>11.5g} "
              f"{r.switching_violation:>10.3e} {r.max_torque_violation:>9.3g} {r.min_normal_grf:>8.3g} "
              f"{r.max_friction_violation:>9.3g} {r.step:>7.3g} {r.mu:>8.2g} {r.wall_time:>7.2f}  {r.event}",
              file=self.stream, flush=True)


class InMemoryLogger:
    """Keeps every record in ``self.records``."""

    def __init__(self) -> None:
        self.records: list[IterationRecord] = []

    def __call__(self, r: IterationRecord) -> None:
        self.records.append(r)
