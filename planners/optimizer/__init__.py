"""The optimizer: hybrid optimal-control problems and HS-DDP (Li & Wensing, RA-L 2020).

* [`.problem`][.problem]: ``HybridProblem`` (phases, dynamics, costs, constraints) and the bounding cost weights;
* [`.objective`][.objective]: cost, augmented-Lagrangian and relaxed-barrier terms, vectorized over the horizon;
* [`.barrier`][.barrier]: the relaxed barrier function;
* [`.riccati`][.riccati]: the impact-aware backward pass (compiled);
* [`.hsddp`][.hsddp]: ``HSDDP``, Algorithm 1 (DDP inside the AL/ReB outer loop);
* [`.sto`][.sto]: switching-time optimization, Algorithm 2, and the open-loop baseline;
* [`.solution`][.solution]: ``SolverOptions``, ``Solution`` (the result, saved as npz) and the iteration log;
* [`.callbacks`][.callbacks], [`.metrics`][.metrics]: solver printers/loggers and trajectory summaries.

Nothing here imports a policy or an environment.
"""
