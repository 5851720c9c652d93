"""Mode schedules: the sequence of contact modes and their durations (the time-switched system, eq. 14)."""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import BACK, FRONT, Mode, as_mode, touchdown_feet
from hsddp_gym.util.validation import check_int, check_positive

PAPER_BOUNDING_DURATIONS = (0.080, 0.072, 0.072, 0.072)
"""Back stance, flight, front stance, flight durations of the paper's tasks [s] (Sec. V-B)."""

BOUNDING_CYCLE = (Mode.BACK_STANCE, Mode.FLIGHT, Mode.FRONT_STANCE, Mode.FLIGHT)


def _durations_array(durations) -> np.ndarray:
    try:
        return np.asarray(durations, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"durations must be numbers [s], got {durations!r}") from None


class ModeSchedule:
    """A sequence of contact modes with durations, and the mode that follows the last one.

    Phase ``i`` lasts ``durations[i]`` seconds in ``modes[i]``; at its end the state jumps through the
    reset map into ``modes[i + 1]`` (``final_mode`` after the last phase). Feet that are in contact after a
    switch but not before it touch down there; the switching constraint (eq. 15) asks their heights to be
    zero at the end of the phase.

    Args:
        modes: ``n`` contact modes (``Mode`` or ints; bools are refused).
        durations: ``n`` positive durations [s].
        final_mode: mode after the last phase (default: ``modes[-1]``, i.e. no switch at the end).
    """

    def __init__(self, modes, durations, final_mode=None) -> None:
        try:
            items = list(modes)
        except TypeError:
            raise ValueError(f"modes must be a sequence of contact modes {[m.name for m in Mode]}, "
                             f"got {modes!r}") from None
        self.modes = tuple(as_mode(m, f"modes[{i}]") for i, m in enumerate(items))
        if not self.modes:
            raise ValueError("modes must hold at least one mode")
        durations = _durations_array(durations)
        if durations.shape != (len(self.modes),):
            raise ValueError(f"durations must have shape ({len(self.modes)},) to match modes, got {durations.shape}")
        if not np.all(np.isfinite(durations)) or np.any(durations <= 0.0):
            raise ValueError(f"durations must be finite and > 0, got {durations}")
        self.durations = durations
        self.durations.setflags(write=False)
        self.final_mode = self.modes[-1] if final_mode is None else as_mode(final_mode, "final_mode")

    # --------------------------------------------------------------------------- factories
    @classmethod
    def bounding(cls, cycles: int = 1, durations=PAPER_BOUNDING_DURATIONS, start: Mode = Mode.BACK_STANCE
                 ) -> ModeSchedule:
        """The bounding gait: back stance -> flight -> front stance -> flight, repeated.

        Args:
            cycles: number of gait cycles (>= 1).
            durations: 4 durations [s] in the order (back stance, flight, front stance, flight), or
                ``4 * cycles`` durations for every phase.
            start: the mode of the first phase (any mode of the cycle; the order is kept).
        """
        cycles = check_int(cycles, "cycles", minimum=1)
        durations = _durations_array(durations)
        if durations.shape == (4,):
            durations = np.tile(durations, cycles)
        elif durations.shape != (4 * cycles,):
            raise ValueError(f"durations must have 4 or {4 * cycles} entries, got shape {durations.shape}")
        start = as_mode(start, "start")
        if start not in (Mode.BACK_STANCE, Mode.FRONT_STANCE):
            raise ValueError(f"start must be BACK_STANCE or FRONT_STANCE, got {start!r}")
        cycle = BOUNDING_CYCLE if start == Mode.BACK_STANCE else BOUNDING_CYCLE[2:] + BOUNDING_CYCLE[:2]
        modes = cycle * cycles
        return cls(modes, durations, final_mode=cycle[0])

    # --------------------------------------------------------------------------- queries
    def __len__(self) -> int:
        return len(self.modes)

    def __repr__(self) -> str:
        body = ", ".join(f"{m.short}:{1e3 * d:.1f}ms" for m, d in zip(self.modes, self.durations))
        return f"ModeSchedule([{body}] -> {self.final_mode.short})"

    def __eq__(self, other) -> bool:
        return (isinstance(other, ModeSchedule) and self.modes == other.modes
                and self.final_mode == other.final_mode and np.array_equal(self.durations, other.durations))

    @property
    def total_time(self) -> float:
        return float(self.durations.sum())

    def next_mode(self, phase: int) -> Mode:
        """The mode entered at the end of ``phase``."""
        return self.modes[phase + 1] if phase + 1 < len(self.modes) else self.final_mode

    def touchdown_feet(self, phase: int) -> tuple[int, ...]:
        """Feet that touch down at the end of ``phase`` (empty for a lift-off or no switch)."""
        return touchdown_feet(self.modes[phase], self.next_mode(phase))

    def knots(self, dt: float) -> np.ndarray:
        """Integration steps per phase, ``N_i = round(T_i / dt)`` (paper Sec. IV-A), (n,) ints >= 1."""
        dt = check_positive(dt, "dt")
        steps = np.rint(self.durations / dt).astype(np.int64)
        if np.any(steps < 1):
            raise ValueError(f"every duration must span at least one step of dt={dt}: {self.durations}")
        return steps

    def with_durations(self, durations) -> ModeSchedule:
        """The same modes with new durations."""
        return ModeSchedule(self.modes, durations, self.final_mode)

    def bounding_touchdown_foot(self, phase: int) -> int | None:
        """For a flight phase, the foot scheduled to touch down at its end (``c_i`` of the paper)."""
        feet = self.touchdown_feet(phase)
        return feet[0] if len(feet) == 1 else None


__all__ = ["ModeSchedule", "PAPER_BOUNDING_DURATIONS", "BOUNDING_CYCLE", "FRONT", "BACK"]
