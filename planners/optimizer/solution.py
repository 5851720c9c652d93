"""Solver options, the per-iteration log and the [`Solution`][Solution] a solve returns."""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from hsddp_gym.core.conventions import NX, Mode
from hsddp_gym.core.schedule import ModeSchedule
from hsddp_gym.util.io import read_npz, write_npz
from hsddp_gym.util.validation import check_in_range, check_int, check_positive, check_vector

METHODS = ("ddp", "al", "al-reb")


@dataclasses.dataclass(frozen=True)
class SolverOptions:
    """Options of HS-DDP Algorithm 1 (defaults: the paper, then the authors' code where the paper is silent).

    Attributes:
        method: ``"ddp"`` impact-aware DDP without switching constraints, ``"al"`` with the augmented
            Lagrangian on them, ``"al-reb"`` with relaxed barriers on torque / normal force / friction.
        max_al_iterations: outer AL iterations at most. al_tolerance: stop when sum g^2 <= it (paper 1e-4).
        al_max_abs_tolerance: None (default, the paper) or a height [m]: the AL loop then also needs the
            largest touchdown-height error ``max |g|`` <= it before it stops (the authors' later code stops on
            ``max |g| < 1e-3``; ``sum g^2 <= 1e-4`` alone allows one landing foot 1 cm off the ground).
        sigma0, beta: AL penalty and its growth (paper: 5, 8). lambda0: initial multipliers (paper: 0).
        max_ddp_iterations: DDP iterations per AL iteration. ddp_tolerance: a DDP run stops when an
            accepted step lowers the objective by less than this (absolute).
        delta_torque0, delta_grf0: initial ReB relaxations (authors' code: 0.2, 0.4);
            delta_factor: shrink per AL iteration (paper: 0.2); delta_min: floor.
        eps_torque, eps_grf: ReB weights per knot; eps_growth: multiplied each AL iteration.
        armijo: accept a step when actual / expected decrease >= armijo. step_factor: backtracking factor;
            min_step: smallest step tried.
        mu_min, mu_growth, mu_max: regularization of Q_uu (mu I): on failure mu <- max(mu_min, mu * growth)
            (mu_min = 1e-3 as in the authors' code);
            after an accepted step mu <- mu / growth (0 below mu_min); give up above mu_max.
        time_limit: wall-clock budget [s] (None: none); reaching it stops with status ``"time_limit"``.
        max_total_ddp_iterations: cap over all AL iterations (None: none).
        refresh_gains: True (default): the returned gains come from one more linearization and backward pass at
            the final trajectory (gains consistent with it, the next step's ``k_ff``). False: when the solve ends
            on an accepted step, the gains ``K`` of the backward pass that made that step are returned, and
            ``k_ff``, ``V_x0``, ``V_xx0`` with them (they belong to the trajectory before the step). Along the
            returned trajectory, ``u = U + K (x - X)`` is then exactly the forward pass's law
            ``U_prev + eps k_ff + K (x - X_prev)``; the final trajectory is not linearized (with
            ``max_total_ddp_iterations``, the last iteration's trial rollout skips its speculative linearization
            too). It saves a linearization and a backward pass per solve: what an MPC that takes one DDP
            iteration per re-plan pays most for.
    """

    method: str = "al-reb"
    max_al_iterations: int = 6
    al_tolerance: float = 1e-4
    al_max_abs_tolerance: float | None = None
    sigma0: float = 5.0
    beta: float = 8.0
    lambda0: float = 0.0
    max_ddp_iterations: int = 10
    ddp_tolerance: float = 1e-3
    delta_torque0: float = 0.2
    delta_grf0: float = 0.4
    delta_factor: float = 0.2
    delta_min: float = 1e-3
    eps_torque: float = 1e-5
    eps_grf: float = 1e-5
    eps_growth: float = 7.0
    armijo: float = 1e-2
    step_factor: float = 0.5
    min_step: float = 1e-3
    mu_min: float = 1e-3
    mu_growth: float = 4.0
    mu_max: float = 1e8
    time_limit: float | None = None
    max_total_ddp_iterations: int | None = None
    refresh_gains: bool = True

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {self.method!r}")
        check_int(self.max_al_iterations, "max_al_iterations", minimum=1)
        check_int(self.max_ddp_iterations, "max_ddp_iterations", minimum=1)
        for name in ("al_tolerance", "sigma0", "ddp_tolerance", "delta_torque0", "delta_grf0", "delta_min",
                     "eps_torque", "eps_grf", "min_step", "mu_min", "mu_max"):
            check_positive(getattr(self, name), name)
        check_positive(self.eps_growth, "eps_growth")
        if not (self.beta > 1.0 and np.isfinite(self.beta)):
            raise ValueError(f"beta must be finite and > 1 (penalty growth), got {self.beta!r}")
        if self.mu_max <= self.mu_min:
            raise ValueError(f"mu_max must be > mu_min, got mu_max={self.mu_max!r}, mu_min={self.mu_min!r}")
        check_in_range(self.delta_factor, 1e-6, 1.0, "delta_factor")
        check_in_range(self.armijo, 0.0, 0.5, "armijo")
        check_in_range(self.step_factor, 1e-3, 0.99, "step_factor")
        if self.mu_growth <= 1.0:
            raise ValueError(f"mu_growth must be > 1, got {self.mu_growth!r}")
        if self.al_max_abs_tolerance is not None:
            check_positive(self.al_max_abs_tolerance, "al_max_abs_tolerance")
        if self.time_limit is not None:
            check_positive(self.time_limit, "time_limit")
        if self.max_total_ddp_iterations is not None:
            check_int(self.max_total_ddp_iterations, "max_total_ddp_iterations", minimum=1)
        if not isinstance(self.refresh_gains, (bool, np.bool_)):
            raise TypeError(f"refresh_gains must be a bool, got {self.refresh_gains!r}")
        if not np.isfinite(self.lambda0):
            raise ValueError(f"lambda0 must be finite, got {self.lambda0!r}")

    @property
    def use_al(self) -> bool:
        return self.method in ("al", "al-reb")

    @property
    def use_reb(self) -> bool:
        return self.method == "al-reb"


@dataclasses.dataclass
class IterationRecord:
    """One line of the solver log (one accepted DDP iteration, or the start of an AL iteration).

    Attributes:
        al_iteration, ddp_iteration: counters (ddp_iteration counts all DDP iterations so far).
        objective: total objective; cost: penalty-free task cost (eq. 18); al, barrier: their terms.
        switching_violation: sum of g^2 over touchdowns. max_torque_violation: max(|u| - u_max, 0) [N m].
        min_normal_grf: smallest stance normal force [N]. max_friction_violation: max(|f_x| - mu f_z) [N].
        step: accepted line-search step (0 at AL starts). mu: regularization. expected: expected decrease.
        wall_time: seconds since the solve started. event: "init", "ddp" or "al_update".
    """

    al_iteration: int
    ddp_iteration: int
    objective: float
    cost: float
    al: float
    barrier: float
    switching_violation: float
    max_torque_violation: float
    min_normal_grf: float
    max_friction_violation: float
    step: float
    mu: float
    expected: float
    wall_time: float
    event: str


LOG_FIELDS = tuple(f.name for f in dataclasses.fields(IterationRecord))


@dataclasses.dataclass
class Solution:
    """The result of an HS-DDP solve.

    Shapes (N knots, n phases): ``X (N+1, 14)``, ``X_pre (n, 14)``, ``U (N, 4)``, ``GRF (N, 4)``,
    ``K (N, 4, 14)`` feedback gains, ``k_ff (N, 4)`` feed-forward terms of the last backward pass,
    ``modes (N,)``, ``phase_start (n+1,)``, ``durations (n,)``, ``switching (m,)`` g of every switching-constraint
    row (one per phase end, 0 where no foot lands, then the second feet of simultaneous touchdowns; ``m = n`` unless
    feet land together), ``multipliers (m,)``.

    The policy of eq. 8 with ``eps = 0`` is ``u = U[k] + K[k] (x - X[k])``.
    """

    X: np.ndarray
    X_pre: np.ndarray
    U: np.ndarray
    GRF: np.ndarray
    K: np.ndarray
    k_ff: np.ndarray
    modes: np.ndarray
    phase_start: np.ndarray
    schedule: ModeSchedule
    dt: float
    switching: np.ndarray
    multipliers: np.ndarray
    sigma: float
    cost: float
    objective: float
    status: str
    converged: bool
    al_iterations: int
    ddp_iterations: int
    solve_time: float
    log: list = dataclasses.field(default_factory=list)
    timings: dict = dataclasses.field(default_factory=dict)
    options: SolverOptions = dataclasses.field(default_factory=SolverOptions)
    V_x0: np.ndarray | None = None
    V_xx0: np.ndarray | None = None

    @property
    def switching_violation(self) -> float:
        """sum of g^2 over touchdowns."""
        return float(np.sum(self.switching ** 2))

    @property
    def phase_dt(self) -> np.ndarray:
        """Step of each phase ``durations / knots`` (n,) [s] (differs from ``dt`` after STO)."""
        return self.schedule.durations / np.diff(self.phase_start)

    @property
    def times(self) -> np.ndarray:
        """``(N+1,)`` time of each state [s], with each phase's own step."""
        h = np.repeat(self.phase_dt, np.diff(self.phase_start))
        return np.concatenate([[0.0], np.cumsum(h)])

    def log_array(self, field: str) -> np.ndarray:
        """One column of the log as an array."""
        if field not in LOG_FIELDS:
            raise ValueError(f"field must be one of {LOG_FIELDS}, got {field!r}")
        return np.array([getattr(r, field) for r in self.log])

    def control(self, k: int, x: np.ndarray) -> np.ndarray:
        """The feedback law ``U[k] + K[k] (x - X[k])`` (4,) at knot ``k`` in ``0 .. N-1`` for a finite state
        ``x`` (14,); negative or out-of-range knots and non-finite states raise ``ValueError``."""
        n = len(self.U)
        if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)):
            raise TypeError(f"k must be an integer knot index, got {type(k).__name__}")
        if not 0 <= k < n:
            raise ValueError(f"k must be a knot index in 0 .. {n - 1}, got {k}")
        x = check_vector(x, NX, "x")
        return self.U[k] + self.K[k] @ (x - self.X[k])

    # ------------------------------------------------------------------ persistence
    def save(self, path) -> None:
        """Save to ``.npz`` (no pickle; metadata as JSON text), atomically."""
        meta = {
            "schedule_modes": [int(m) for m in self.schedule.modes],
            "final_mode": int(self.schedule.final_mode),
            "durations": self.schedule.durations.tolist(),
            "dt": self.dt, "sigma": self.sigma, "cost": self.cost, "objective": self.objective,
            "status": self.status, "converged": self.converged, "al_iterations": self.al_iterations,
            "ddp_iterations": self.ddp_iterations, "solve_time": self.solve_time, "timings": self.timings,
            "options": dataclasses.asdict(self.options),
        }
        log = np.array([[float(getattr(r, f)) if f != "event" else 0.0 for f in LOG_FIELDS] for r in self.log]
                       ).reshape(len(self.log), len(LOG_FIELDS))
        events = np.array([r.event for r in self.log], dtype="U16")
        arrays = dict(X=self.X, X_pre=self.X_pre, U=self.U, GRF=self.GRF, K=self.K, k_ff=self.k_ff,
                      modes=self.modes, phase_start=self.phase_start, switching=self.switching,
                      multipliers=self.multipliers, log=log, log_events=events,
                      meta=np.array(json.dumps(meta)))
        if self.V_x0 is not None:
            arrays["V_x0"] = self.V_x0
            arrays["V_xx0"] = self.V_xx0
        write_npz(path, **arrays)

    @classmethod
    def load(cls, path) -> Solution:
        """Load a solution written by [`save`][save] (never unpickles).

        Raises:
            FileNotFoundError: ``path`` does not exist.
            ValueError: ``path`` is no ``.npz`` file, holds object arrays, or is an npz of something else
                (the message names the missing arrays).
        """
        import os
        import zipfile

        if not os.path.exists(path):
            raise FileNotFoundError(f"no Solution file at {path}")
        if not zipfile.is_zipfile(path):
            raise ValueError(f"{path} is not a Solution file: it is not an .npz archive (Solution.save writes one)")
        try:
            d = read_npz(path)
        except (zipfile.BadZipFile, OSError, EOFError, ValueError) as exc:  # e.g. pickled (object) arrays
            raise ValueError(f"{path} is not a Solution file written by Solution.save (plain arrays; nothing is "
                             f"ever unpickled): {type(exc).__name__}") from None
        needed = ("X", "X_pre", "U", "GRF", "K", "k_ff", "modes", "phase_start", "switching", "multipliers", "log",
                  "log_events", "meta")
        absent = [k for k in needed if k not in d]
        if absent:
            raise ValueError(f"{path} is not a Solution file written by Solution.save: it lacks the arrays "
                             f"{', '.join(absent)} (it holds {', '.join(sorted(d)) or 'no arrays'})")
        meta = json.loads(str(d["meta"]))
        schedule = ModeSchedule([Mode(m) for m in meta["schedule_modes"]], meta["durations"], meta["final_mode"])
        log = []
        for row, ev in zip(d["log"], d["log_events"]):
            values = dict(zip(LOG_FIELDS, row.tolist()))
            values["event"] = str(ev)
            values["al_iteration"] = int(values["al_iteration"])
            values["ddp_iteration"] = int(values["ddp_iteration"])
            log.append(IterationRecord(**values))
        return cls(X=d["X"], X_pre=d["X_pre"], U=d["U"], GRF=d["GRF"], K=d["K"], k_ff=d["k_ff"], modes=d["modes"],
                   phase_start=d["phase_start"], schedule=schedule, dt=meta["dt"], switching=d["switching"],
                   multipliers=d["multipliers"], sigma=meta["sigma"], cost=meta["cost"], objective=meta["objective"],
                   status=meta["status"], converged=meta["converged"], al_iterations=meta["al_iterations"],
                   ddp_iterations=meta["ddp_iterations"], solve_time=meta["solve_time"], log=log,
                   timings=meta["timings"], options=SolverOptions(**meta["options"]),
                   V_x0=d.get("V_x0"), V_xx0=d.get("V_xx0"))
