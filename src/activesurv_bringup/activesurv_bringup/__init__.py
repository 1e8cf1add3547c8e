"""Bringing up runs: experiments and surveillance sessions on the node graph or in lockstep,
commissioning and rigs, rosbag2 recording and replay, reports, the live view.

Rooms: :mod:`.launching` (processes and containers), :mod:`.recording` (bags),
:mod:`.rig` (rigs, commissioning, the lab), :mod:`.experiments` (runs, evaluation, reports),
:mod:`.liveview` (Foxglove); :mod:`.cli` is the ``activesurv`` command.
"""

from activesurv_bringup import _moved

__version__ = '0.9.0'

# Earlier flat module paths (activesurv_bringup.graph, ...) stay importable.
_moved.install()
