"""The plans' forward-speed reference: a start-up ramp, integral action and a reference governor."""

from __future__ import annotations

import collections

import numpy as np

from hsddp_gym.core.conventions import NQ
from hsddp_gym.planners.policies.mpc.options import SpeedOptions


class SpeedReference:
    """The forward speed the MPC's plans aim at.

    * [`reference`][reference] is the target speed reached from the speed of the episode's first estimate at most at
      ``acceleration`` (a start-up that does not ask a robot at rest for the full speed within one gait cycle);
    * [`bias`][hsddp_gym.core.batch_model.bias] is integral action: at every periodic re-plan, once a whole gait cycle
    has been seen, it moves by
      ``integral_gain * (time since the last update) * (mean reference - mean estimated speed)`` over the last cycle
      (both means over the same steps, so neither the within-cycle speed swing nor a ramping reference winds it up),
      within ``+- bias_limit``: offset-free speed tracking whatever makes the closed loop lag its plans;
    * [`plan_speed`][plan_speed] is reference plus bias, moved at most ``ramp`` from the measured speed (a reference
    governor:
      after a push a plan does not demand the whole change of speed within one gait cycle).

    Args:
        target: the target speed [m/s].
        cycle_steps: control steps per gait cycle (the integral's averaging window).
        options: [`SpeedOptions`][hsddp_gym.planners.policies.mpc.options.SpeedOptions].
    """

    def __init__(self, target: float, cycle_steps: int, options: SpeedOptions) -> None:
        self.target = float(target)
        self.options = options
        self._cycle_steps = max(1, int(cycle_steps))
        self.reset()

    def reset(self) -> None:
        self.time = 0.0
        """Env time since the episode's start [s]."""
        self.start_speed: float | None = None
        self.bias = 0.0
        """The integral action on the plans' speed reference [m/s]."""
        self._vx = collections.deque(maxlen=self._cycle_steps)  # estimated forward speeds of the last gait cycle
        self._ref = collections.deque(maxlen=self._cycle_steps)  # the speed references at the same steps
        self._bias_time = 0.0

    def observe(self, vx: float) -> None:
        """The estimated forward speed [m/s] of this control step (the first one is the start speed)."""
        if self.start_speed is None:
            self.start_speed = float(vx)
        self._vx.append(float(vx))
        self._ref.append(self.reference())

    def tick(self, dt: float) -> None:
        """``dt`` seconds of env time have passed."""
        self.time += dt

    def reference(self) -> float:
        """The forward speed [m/s] the robot should have now: the target, reached from the episode's start speed at
        ``acceleration`` at most."""
        target = self.target
        acc = self.options.acceleration
        if acc is not None and self.start_speed is not None:
            reach = acc * self.time
            target = min(max(target, self.start_speed - reach), self.start_speed + reach)
        return float(target)

    def update_bias(self) -> None:
        """Integral action (see the class docstring), called at every periodic re-plan."""
        gain = self.options.integral_gain
        elapsed, self._bias_time = self.time - self._bias_time, self.time
        if gain is None or len(self._vx) < self._vx.maxlen:
            return
        err = (sum(self._ref) - sum(self._vx)) / len(self._vx)
        lim = self.options.bias_limit
        self.bias = float(min(max(self.bias + gain * elapsed * err, -lim), lim))

    def plan_speed(self, x: np.ndarray) -> float:
        """The forward-speed reference [m/s] of a plan from state ``x`` (14,): [`reference`][reference] plus
        [`bias`][hsddp_gym.core.batch_model.bias], moved at most ``ramp`` from the measured speed (None: not moved)."""
        target = self.reference() + self.bias
        ramp = self.options.ramp
        if ramp is None:
            return float(target)
        vx = float(x[NQ])
        return float(min(max(target, vx - ramp), vx + ramp))
