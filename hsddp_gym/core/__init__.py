"""The robot core: conventions (state order, modes, signs), parameters, the Pinocchio model, hybrid dynamics
and their derivatives, references, mode schedules, rollouts and the observation layout.

Everything else in the package builds on this layer; it imports nothing above it.
"""
