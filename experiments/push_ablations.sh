#!/usr/bin/env bash
# The ablations of the MPC's push recovery quoted in the README ("Pushes"), each a push_robustness.py run with
# one MPCOptions change, on the phase-swept grid (6 push times x seeds 100, 101) or at t = 1 s (10 seeds).
# Run from the repository root in the project's venv; about 3 minutes on 2 cores. Results in runs/push_ablation_*.
set -euo pipefail
cd "$(dirname "$0")/.."
T="1.0 1.05 1.1 1.15 1.2 1.25"
run() { python experiments/push_robustness.py --policies mpc-options --workers 2 "$@"; }
# the 5 ms recovery without its double stance, on the downward pushes
run --out runs/push_ablation_no_double_stance --mpc-options '{"recovery": true, "recovery_double_stance": null}' \
    --push 0 -1 0 --push 0 -1.5 0 --push 0 -2.5 0 --seeds 2 --times $T
# the 5 ms recovery without ending a flight at any touchdown, on the nose-down pushes (swept and at t = 1 s)
run --out runs/push_ablation_min_flight --mpc-options '{"recovery": true, "recovery_min_flight": null}' \
    --push 0 0 6 --push 0 0 8 --push 0 0 10 --seeds 2 --times $T
run --out runs/push_ablation_min_flight_t1 --mpc-options '{"recovery": true, "recovery_min_flight": null}' \
    --push 0 0 9 --push 0 0 10 --seeds 10
# the plain MPC on the 2.5 ms grid (no recovery), on the five hardest pushes
run --out runs/push_ablation_plain_2p5ms --mpc-options '{"planner_dt": 0.0025}' \
    --push 0 -1.5 0 --push 0 0 -10 --push 0 0 10 --push 3 0 0 --push 0 0 -6 --seeds 2 --times $T
