"""Runs: experiment definitions, the node graph and lockstep, faults, evaluation, reports,
surveillance."""
