"""Bringing up runs: experiments and surveillance sessions on the node graph or in lockstep,
commissioning and rigs, rosbag2 recording and replay, reports.

Rooms: :mod:`.rig` (rigs, hardware files, commissioning, the lab, measured delays),
:mod:`.experiments` (runs, evaluation, reports); :mod:`.cli` is the ``activesurv`` command.
Launching is :mod:`activesurv_launch`, recording :mod:`activesurv_recording`, the live view
:mod:`activesurv_liveview`.
"""

__version__ = '0.9.0'
