"""Things in the way: obstacles in the rig are rendered, an imager behind one says
"occluded", the dispatcher never assigns a camera whose view is blocked, and results say which
assigned cameras were occluded (issue 27's occlusion, eq. 1 in full)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.occlusion import Box, Cylinder, sight_blocked
from activesurv_common.sensor_model import SensorModel
from activesurv_common.statuses import ObservationStatus
from activesurv_imaging.capture import CaptureCore, ImagerConfig
from activesurv_sim.render import Plate, Renderer, Scene, SensorNoise, look_at
from activesurv_sim.sim_camera import OBSTACLE_LEVEL, obstacle_plates

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')
MARKER = np.array([0.25, 0.10, 0.05])
NORMAL = np.array([0.0, -1.0, 0.0])
EYE = MARKER + np.array([0.0, -0.45, 0.0])
WALL = Box((0.25, -0.1, 0.05), (0.08, 0.02, 0.1))  # between the camera and the marker
POST = Cylinder((0.25, -0.1, 0.05), 0.03, 0.1)


def _frame(obstacles: tuple[Box | Cylinder, ...]) -> np.ndarray:
    cam = dynamic_camera('cam1')
    scene = Scene((Plate.disc(MARKER, NORMAL, 0.0125), *obstacle_plates(obstacles)))
    return Renderer(cam).render(look_at(EYE, MARKER), scene, SensorNoise(0.0, 0.0, 0.0))


@pytest.mark.cross
@pytest.mark.parametrize('obstacle', [WALL, POST], ids=['box', 'cylinder'])
def test_an_obstacle_is_drawn_over_the_marker_behind_it(obstacle: Box | Cylinder) -> None:
    clear, hidden = _frame(()), _frame((obstacle,))
    cam = dynamic_camera('cam1')
    u, v = round(cam.cx), round(cam.cy)  # the marker's centre, straight ahead
    assert clear[v, u] > 200
    assert abs(int(hidden[v, u]) - OBSTACLE_LEVEL) < 10
    assert sight_blocked(EYE, MARKER, [obstacle], 0.0125, NORMAL)[0]
    # Seen from behind the marker, the obstacle is not drawn in front of anything.
    assert not sight_blocked(MARKER + [0, 0.3, 0], MARKER, [obstacle], 0.0125, NORMAL)[0]


@pytest.mark.cross
def test_the_imager_says_occluded_when_an_obstacle_hides_the_marker() -> None:
    cam = dynamic_camera('cam1')
    for obstacles, occluded in [((), False), ((WALL,), True)]:
        config = ImagerConfig('cam1', 0.0125, obstacles=obstacles)
        core = CaptureCore(config, look_at(EYE, MARKER), SensorModel.load(None), lambda g: g, cam)
        core.request(0, 1.0, NORMAL, position=MARKER)
        core.add_frame(1.0, _frame((WALL,)))
        (obs,) = core.poll(1.1)
        assert obs.status is not ObservationStatus.OK  # the wall really hides it
        assert obs.reason.startswith('occluded') is occluded, obs.reason


@pytest.mark.cli
def test_no_assigned_camera_is_occluded_and_results_say_so(tmp_path: Path) -> None:
    """Lockstep on the nominal rig with a post in front of cam3 and cam4 for the second half
    of the path: every demand record has ``object`` and ``occluded`` (empty: the dispatcher
    never assigns a blocked camera), and the cameras that would have been blocked are not
    used where the post stands between them and the marker."""
    rig = tmp_path / 'rig.yaml'
    subprocess.run([ACTIVESURV, 'rig', 'nominal', '--out', str(rig)], check=True)
    data = yaml.safe_load(rig.read_text())
    assert data['obstacles'] == []
    data['obstacles'] = [
        {'kind': 'cylinder', 'centre': [0.40, -0.25, 0.05], 'radius': 0.02, 'height': 0.1}
    ]
    rig.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / 'run'
    subprocess.run(
        [ACTIVESURV, 'experiment', '--set', 'A', '--system', 'fast', '--mode', 'lockstep']
        + ['--rig', str(rig), '--calibration', 'truth', '--out', str(out)],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    doc = json.loads((out / 'results.json').read_text())
    assert all(d['object'] == 0 for d in doc['demands'])
    assert all(d['occluded'] == [] for d in doc['demands'])
    assert sum(d['status'] == 'ok' for d in doc['demands']) >= 8
    post = Cylinder((0.40, -0.25, 0.05), 0.02, 0.1)
    # The post really blocks some camera's view of the later demands from where it waited:
    # the test would not test anything otherwise.
    blocked_any = False
    for d in doc['demands']:
        for base in ([0.48, -0.5, 0.05], [0.48, -0.42, 0.05]):
            blocked_any |= bool(
                sight_blocked(base, d['true_position'], [post], 0.0125, d['true_normal'])[0]
            )
    assert blocked_any
