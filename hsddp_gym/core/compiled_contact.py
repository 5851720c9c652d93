"""One robot through the compiled contact kernel: [`CompiledContactSimulator`][CompiledContactSimulator], the
[`ContactSimulator`][hsddp_gym.core.contact.ContactSimulator] whose [`run`][CompiledContactSimulator.run] is one call of
[`step_batch`][hsddp_gym.core.batch_contact.step_batch] (or
[`step_batch_terrain`][hsddp_gym.core.batch_contact.step_batch_terrain] on a terrain) on a batch of one."""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.batch_contact import kernel_scratch, step_batch, step_batch_terrain, warm_up
from hsddp_gym.core.batch_model import kernel_params, model_cache
from hsddp_gym.core.contact import ContactSimulator
from hsddp_gym.core.conventions import NQ, NX
from hsddp_gym.core.terrain import check_terrain


def _counter_property(index: int, name: str) -> property:
    def get(self) -> int:
        return int(self._counters_b[0, index])

    def set_(self, value) -> None:
        self._counters_b[0, index] = value

    return property(get, set_, doc=f"``{name}`` of [`ContactSimulator`][ContactSimulator], counted by the kernel.")


class CompiledContactSimulator(ContactSimulator):
    """[`ContactSimulator`][ContactSimulator]'s energy-consistent scheme stepped by the compiled kernel: [`run`][run] is
    one [`step_batch`][hsddp_gym.core.batch_contact.step_batch] call on a batch of one robot, the same compiled code the
    vector env ([`hsddp_gym.envs.vector`][hsddp_gym.envs.vector]) runs for N robots, so a single env and the vector env
    produce bit-identical states from the same inputs. ``hsddp_gym/Bounding-v0`` uses it for ``energy_consistent=True``;
    [`ContactSimulator`][ContactSimulator] stays the readable reference (the MPC's predictor,
    [`ContactModelPredictor`][hsddp_gym.planners.policies.estimation.ContactModelPredictor], uses this one); the two
    agree to round-off (``tests/test_vector_env.py``: 1e-11 relative, median 4e-16).

    Same arguments as [`ContactSimulator`][ContactSimulator] without ``erp`` and ``energy_consistent`` (the legacy
    scheme is not compiled), and the same attributes, with these differences: ``x`` (with its views ``q``, ``v``),
    ``states`` (an int64 array (2,)), ``contact``, ``time`` and the counters live in the kernel's batch-of-one
    arrays (assigning to them writes into those); ``impulse`` holds the impulses summed over the last
    [`run`][run] call (the last step's for ``run(u, 1)``), which is also what [`run`][run] returns (an array, reused
    by the next call); ``projection_residual`` is not tracked (stays 0). [`foot_heights_fast`][foot_heights_fast]
    returns the kernel's foot heights of the state the last [`run`][run] left (Pinocchio's after
    [`set_state`][set_state]; pushes change only ``v``). ``_tau`` holds the torques the motors applied in the last step,
    as in [`ContactSimulator`][ContactSimulator]. `energy` and the other queries are Pinocchio's, as in
    [`ContactSimulator`][ContactSimulator]. ``terrain`` (a [`Terrain`][hsddp_gym.core.terrain.Terrain] or None,
    [`set_terrain`][set_terrain]): stepped by [`step_batch_terrain`][hsddp_gym.core.batch_contact.step_batch_terrain]
    (compiled on first use), the feet's heights above its surface. The kernel is compiled once per machine
    ([`warm_up`][hsddp_gym.core.batch_contact.warm_up], announced on stderr) when the first one is built.
    """

    lcp_fallbacks = _counter_property(0, "lcp_fallbacks")
    energy_projections = _counter_property(1, "energy_projections")
    momentum_fallbacks = _counter_property(2, "momentum_fallbacks")
    energy_deficits = _counter_property(3, "energy_deficits")

    def __init__(self, robot=None, timestep: float = 1e-3, friction: float | None = None,
                 gravity: float | None = None, motor_speed_limits=None, torque_limit: float | None = None,
                 terrain=None) -> None:
        # batch-of-one arrays the kernel works in (created before ContactSimulator.__init__ assigns through
        # the properties below)
        self._xb = np.zeros((1, NX))
        self._ub = np.zeros((1, 4))
        self._states_b = np.zeros((1, 2), dtype=np.int64)
        self._contact_b = np.zeros((1, 2), dtype=np.bool_)
        self._total_b = np.zeros((1, 4))
        self._time_b = np.zeros(1)
        self._heights_b = np.zeros((1, 2))
        self._counters_b = np.zeros((1, 4), dtype=np.int64)
        self._cache_b = model_cache(1)
        self._active = np.ones(1, dtype=np.bool_)
        self._heights_valid = False
        super().__init__(robot, timestep=timestep, friction=friction, gravity=gravity,
                         motor_speed_limits=motor_speed_limits, torque_limit=torque_limit, energy_consistent=True)
        self.terrain = check_terrain(terrain)
        self._p = kernel_params(self)
        self._sc = kernel_scratch()
        self._link_views()
        warm_up()

    def _link_views(self) -> None:
        """The attributes that are views of the batch-of-one arrays (again after a copy, which copies views
        as separate arrays)."""
        self.x = self._xb[0]
        self.q = self.x[:NQ]
        self.v = self.x[NQ:]
        self.contact = self._contact_b[0]
        self._total = self._total_b[0]
        self._u = self._ub[0]
        self._tau = self._sc.tau  # the applied torques of the last step (the kernel's), as ContactSimulator's

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._link_views()

    # state kept in the kernel's arrays
    @property
    def time(self) -> float:
        """Simulated time since [`set_state`][set_state] [s] (accumulated ``+= h`` per step by the kernel)."""
        return float(self._time_b[0])

    @time.setter
    def time(self, value: float) -> None:
        self._time_b[0] = value

    @property
    def states(self) -> np.ndarray:
        """Per-foot contact state of the last step, int64 (2,) (a view: writes set the LCP's first guess)."""
        return self._states_b[0]

    @states.setter
    def states(self, value) -> None:
        self._states_b[0] = value

    @property
    def impulse(self) -> np.ndarray:
        """Ground impulses summed over the last [`run`][run] call [N s], grf layout (4,)."""
        return self._total_b[0]

    @impulse.setter
    def impulse(self, value) -> None:
        self._total_b[0] = value

    def set_state(self, x: np.ndarray) -> None:
        """Set the state ``x`` (14,), reset the clock, contact states and impulses."""
        super().set_state(x)
        self._heights_valid = False

    def set_terrain(self, terrain) -> None:
        """Simulate on ``terrain`` (a [`Terrain`][hsddp_gym.core.terrain.Terrain], or None: the flat ground) from now
        on: the kernel's parameters get its surface ([`kernel_params`][hsddp_gym.core.batch_model.kernel_params])."""
        self.terrain = check_terrain(terrain)
        self._p = kernel_params(self)
        self._heights_valid = False

    def foot_heights_fast(self) -> tuple[float, float]:
        """Foot heights ``(front, back)`` above the ground (with a terrain: above its surface under each foot): the
        kernel's after a [`run`][run], Pinocchio's after [`set_state`][set_state]."""
        if self._heights_valid:
            h = self._heights_b[0]
            return float(h[0]), float(h[1])
        if self.terrain is not None:
            h = self.foot_heights()
            return float(h[0]), float(h[1])
        return super().foot_heights_fast()

    def run(self, u: np.ndarray, n: int) -> np.ndarray:
        """``n`` steps with constant commanded joint torques ``u`` (4,) (unchecked: the env validates), in one
        compiled call.

        Returns:
            The summed ground impulses over the ``n`` steps, grf layout (4,) [N s] (an array reused by the next call).
        """
        self._u[:] = u
        kernel = step_batch if self.terrain is None else step_batch_terrain
        kernel(self._p, self._xb, self._ub, n, self._active, self._states_b, self._contact_b, self._total_b,
               self._time_b, self._heights_b, self._counters_b, self._cache_b, self._sc)
        self._heights_valid = True
        return self._total


_BATCH_ARRAYS = ("_xb", "_ub", "_states_b", "_contact_b", "_total_b", "_time_b", "_heights_b", "_counters_b",
                 "_cache_b")
"""The batch-of-one arrays of a [`CompiledContactSimulator`][CompiledContactSimulator] that a
[`SimulatorBatch`][SimulatorBatch] turns into rows of its shared arrays."""


class SimulatorBatch:
    """N [`CompiledContactSimulator`][CompiledContactSimulator] stepped together: their kernel arrays become rows of
    shared ``(N, ...)`` arrays (each simulator keeps working on its own row, [`run`][CompiledContactSimulator.run]
    included), so that [`run`][SimulatorBatch.run] steps any subset of them in one kernel call per distinct parameter
    vector (one call when they share robot, friction and terrain). Each robot's numbers are bit-identical to its own
    ``run``: the kernel steps the robots of a batch independently, in the same arithmetic.

    The simulators' current states, contact states, clocks and counters are carried over into the shared rows. The
    applied torques of the last step (``_tau``) are not kept per robot by a batched call.

    Args:
        sims: the simulators (a sequence of N >= 1 [`CompiledContactSimulator`][CompiledContactSimulator], distinct
            objects).
    """

    def __init__(self, sims) -> None:
        sims = list(sims)
        if not sims:
            raise ValueError("sims must hold at least one simulator")
        for i, sim in enumerate(sims):
            if not isinstance(sim, CompiledContactSimulator):
                raise TypeError(f"sims[{i}] must be a CompiledContactSimulator, got {type(sim).__name__}")
        if len({id(sim) for sim in sims}) != len(sims):
            raise ValueError("sims must be distinct simulators")
        self.sims = sims
        n = len(sims)
        self.arrays = {name: np.zeros((n,) + getattr(sims[0], name).shape[1:], dtype=getattr(sims[0], name).dtype)
                       for name in _BATCH_ARRAYS}
        """The shared arrays, by the simulators' attribute names: ``_xb`` (N, 14) states, ``_ub`` (N, 4) commanded
        torques, ``_states_b``, ``_contact_b``, ``_heights_b`` (N, 2), ``_total_b`` (N, 4) impulses, ``_time_b`` (N,),
        ``_counters_b`` (N, 4), ``_cache_b`` the model caches."""
        for i, sim in enumerate(sims):
            for name, shared in self.arrays.items():
                row = shared[i:i + 1]
                row[...] = getattr(sim, name)
                setattr(sim, name, row)
            sim._link_views()
        self._sc = kernel_scratch()
        self._params: list = [None] * n  # each simulator's parameter vector when last grouped, and its bytes
        self._keys: list = [b""] * n

    def _groups(self, active: np.ndarray) -> list:
        """``[(p, on_terrain, mask), ...]``: the robots of ``active`` grouped by equal kernel parameters (``p`` the
        group's, ``on_terrain`` whether it holds a terrain, ``mask`` (N,) bool the group's robots)."""
        groups: dict = {}
        for i in np.flatnonzero(active):
            sim = self.sims[i]
            if sim._p is not self._params[i]:  # a new terrain (set_terrain) or a new simulator setting
                self._params[i] = sim._p
                self._keys[i] = sim._p.tobytes()
            key = self._keys[i]
            if key not in groups:
                groups[key] = (sim, np.zeros(len(self.sims), dtype=np.bool_))
            groups[key][1][i] = True
        return [(sim._p, sim.terrain is not None, mask) for sim, mask in groups.values()]

    def run(self, active: np.ndarray, n: int) -> None:
        """``n`` simulation steps of the robots with ``active[i]`` ((N,) bool; the others are left untouched), each
        with its commanded torques (its row of ``arrays["_ub"]``, written by the caller) and its own parameters;
        afterwards each stepped robot's ``impulse`` holds its impulses summed over the ``n`` steps, as after its own
        ``run(u, n)``."""
        a = self.arrays
        for p, on_terrain, mask in self._groups(active):
            kernel = step_batch_terrain if on_terrain else step_batch
            kernel(p, a["_xb"], a["_ub"], n, mask, a["_states_b"], a["_contact_b"], a["_total_b"], a["_time_b"],
                   a["_heights_b"], a["_counters_b"], a["_cache_b"], self._sc)
        for i in np.flatnonzero(active):
            self.sims[i]._heights_valid = True
