"""The optimizer: hybrid optimal-control problems and HS-DDP (Li & Wensing, RA-L 2020).

* :mod:`.problem`: ``HybridProblem`` (phases, dynamics, costs, constraints) and the bounding cost weights;
* :mod:`.objective`: cost, augmented-Lagrangian and relaxed-barrier terms, vectorized over the horizon;
* :mod:`.barrier`: the relaxed barrier function;
* :mod:`.riccati`: the impact-aware backward pass (compiled);
* :mod:`.hsddp`: ``HSDDP``, Algorithm 1 (DDP inside the AL/ReB outer loop);
* :mod:`.sto`: switching-time optimization, Algorithm 2, and the open-loop baseline;
* :mod:`.solution`: ``SolverOptions``, ``Solution`` (the result, saved as npz) and the iteration log;
* :mod:`.callbacks`, :mod:`.metrics`: solver printers/loggers and trajectory summaries.

Nothing here imports a policy or an environment.
"""
