"""Parameters of the ``xy_table`` node (``config/xy_table.yaml`` is generated from them)."""

from __future__ import annotations

from activesurv_common.ros.parameters import Param
from activesurv_sim.stream import PATH_KINDS

PARAMS = (
    Param('path_type', 'parabola', 'object path', choices=('parabola', 'line', 'csv', 'stream')),
    Param(
        'path_points',
        [0.17, 0.06, 0.25, 0.12, 0.33, 0.06],
        'line: x0, y0, x1, y1; parabola: start, apex, end (m)',
    ),
    Param('csv_file', '', 't,x,y CSV for path_type csv'),
    Param('enters_at_start', False, 'the object is out of the workspace until start_time'),
    Param('rig_file', '', "rig YAML: the table's true position errors; empty: exact"),
    Param('speed', 0.02, 'path speed (m/s)', above=0.0),
    Param('acceleration', 0.02, 'path acceleration (m/s^2)', above=0.0),
    Param('start_time', 1.0, 's before the object starts', minimum=0.0),
    Param('top_height', 0.08, 'top marker plane z (m)'),
    Param('side_offset', [0.0, -0.03, -0.03], 'side marker centre minus top marker centre (m)'),
    Param('side_normal', [0.0, -1.0, 0.0], 'side marker normal (world)'),
    Param('publish_rate', 50.0, 'object_state rate (Hz)', above=0.0),
    Param('publish_phase', 0.0, 's: states at phase + n / rate (0: as the timer ticks)'),
    Param('publish_clock', True, 'own the simulated /clock'),
    Param('real_time_factor', 1.0, 'simulated s per wall s', above=0.0),
    Param('frame_id', 'world', 'frame of object_state'),
    Param('wait_for_subscribers', 0, 'hold time at 0 until object_state has this many', minimum=0),
    Param('wait_for_clock_subscribers', 0, 'and until /clock has this many', minimum=0),
    Param(
        'wait_for_instant_subscribers',
        0,
        'and until sim/instant_object_state has this many (with demand_states)',
        minimum=0,
    ),
    Param('wait_timeout', 30.0, 's to wait for them at most', minimum=0.0),
    Param('hold_until_released', False, 'and until /sim/time_release (the orchestrator)'),
    Param('stream_seed', 0, "stream: seed of the objects' paths"),
    Param('arrival_interval', 30.0, "stream: s from one object's entry to the next", above=0.0),
    Param('path_kinds', list(PATH_KINDS), 'stream: path kinds to draw from'),
    Param('objects_at_once', 1, 'stream: objects on the table at once (lanes)', minimum=1),
    Param('stream_script', '', 'stream: JSON list of scripted objects instead of drawn ones'),
    Param('demand_states', True, 'publish a state (and clock tick) at each demand instant'),
    Param('instant_ticks', True, 'with demand_states: a /clock tick at each instant too'),
    Param(
        'instant_state_delay',
        0.0,
        's (simulated) an instant state waits when it has no tick: past the imaging',
        minimum=0.0,
        maximum=1.0,
    ),
    Param(
        'clock_period',
        0.0,
        's: least simulated time between regular /clock ticks (0: one with every state)',
        minimum=0.0,
    ),
)
