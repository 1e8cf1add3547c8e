"""The test session is isolated from every other ROS user of this shared machine."""

from __future__ import annotations

import fcntl
import os
import tempfile
from pathlib import Path

import pytest

from activesurv_launch.domains import DOMAIN_IDS

pytestmark = pytest.mark.meta


def test_session_has_its_own_ros_environment() -> None:
    domain = int(os.environ['ROS_DOMAIN_ID'])
    assert domain in DOMAIN_IDS  # never 0, the domain every ROS 2 tool uses
    assert os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    ros_home = Path(os.environ['ROS_HOME'])
    assert ros_home.is_dir()
    assert str(ros_home).startswith(tempfile.gettempdir())
    assert os.environ['ROS_LOG_DIR'].startswith(str(ros_home))
    assert 'ROS_LOCALHOST_ONLY' not in os.environ


def test_domain_id_is_locked_against_other_sessions() -> None:
    lock = (
        Path(tempfile.gettempdir())
        / 'activesurv-ros-domains'
        / (f'{os.environ["ROS_DOMAIN_ID"]}.lock')
    )
    with open(lock, 'w') as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return  # held by this session, as it should be
        fcntl.flock(handle, fcntl.LOCK_UN)
    raise AssertionError('the session does not hold the lock on its ROS_DOMAIN_ID')
