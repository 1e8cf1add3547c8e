"""Dispatching module: visibility, best achievable poses, assignment, preassignment,
replanning, motion control and initial-pose determination."""
