"""Dispatching module: visibility, best achievable poses, assignment, preassignment, replanning, motion control, initial poses."""
