"""Parameters of the ``recorder`` node (``config/recorder.yaml`` is generated from them)."""

from __future__ import annotations

from activesurv_common.ros.parameters import Param

PARAMS = (
    Param('output', '', 'bag directory (must not exist)'),
    Param('image_rate', 2.0, 'Hz per thinned topic; 0: all', minimum=0.0),
    Param('exclude', ['/rosout', '/parameter_events'], 'topics not recorded'),
    Param('strip_namespace', '', "a rig's namespace: /NS/x is recorded as /x"),
    Param('discovery_period', 0.5, 's between topic discoveries', above=0.0),
    Param(
        'discovery_period_max',
        4.0,
        's between discoveries that find nothing (doubling; at least discovery_period)',
        above=0.0,
    ),
    Param('run_info', '{}', 'JSON stored in the bag'),
    Param('flush_period', 0.5, 's between flushes to disk (SIGKILL loses less)', above=0.0),
    Param(
        'max_bag_duration', 0.0, 'split the bag into files of this many s (0: one)', minimum=0.0
    ),
    Param(
        'max_bag_size', 0.0, 'split the bag into files of this many MB (0: no limit)', minimum=0.0
    ),
    Param('keep_bags', 0, 'keep only the newest N files of a split bag (0: all)', minimum=0),
    Param(
        'thin_topics',
        ['/overhead/image_raw', '/overhead/camera_info'],
        'streams thinned to image_rate',
    ),
)
