"""A stage bridge's diagnostics as the dispatcher reads them: faults of this rig only."""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from activesurv_dispatch.conversions import stage_faults


def _status(cid: str, level: bytes, message: str, namespace: str) -> DiagnosticStatus:
    s = DiagnosticStatus(name=f'activesurv/stage_bridge/{cid}', message=message)
    s.level = level
    s.values = [KeyValue(key='namespace', value=namespace)]
    return s


def test_errors_of_this_rig_are_faults_and_others_are_not() -> None:
    msg = DiagnosticArray(
        status=[
            _status('cam1', DiagnosticStatus.ERROR, 'e-stop raised: goals refused', '/lab'),
            _status('cam2', DiagnosticStatus.OK, 'ready', '/lab'),
            _status('cam3', DiagnosticStatus.ERROR, 'disconnected', '/other_rig'),
            DiagnosticStatus(name='activesurv/imager/cam1', message='x'),
        ]
    )
    assert stage_faults(msg, 'lab') == {'cam1': 'e-stop raised: goals refused', 'cam2': ''}
