"""The experiments' shared evaluations: the task evaluations, the robustness and push benchmarks, the policy
comparison. ``experiments/*.py`` are thin command lines over them (they import the package, never each other).

The top layer beside the reports (it may use learning, datasets and everything below).
"""
