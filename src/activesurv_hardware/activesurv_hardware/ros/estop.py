"""``activesurv stop --hardware HW.yaml [--release]``: the rig's e-stop from a second terminal.

It publishes ``<namespace>/estop`` (``std_msgs/Bool``, reliable + transient local) and waits
until every stage bridge of the hardware file (each camera's stages, the table's) reports in its
diagnostics that the e-stop is raised and its axes stand still (``--release``: that it is
lowered). A bridge that confirms nothing within the timeout is named: it is not running, runs
in another ROS domain or namespace, or its controller does not answer.

Every bridge keeps the e-stop once it has seen it, after this command exits, until a
``--release``: a run started meanwhile has every goal refused and says so. A bridge started
after this command exited does not know of it: raise it again.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Bool

from activesurv_common.ros import qos, topics
from activesurv_hardware.errors import HardwareError
from activesurv_hardware.hardware_file import Hardware
from activesurv_sim.xytable import TABLE_ID


class EstopError(HardwareError):
    """The e-stop could not be confirmed (a bridge did not answer), or nothing to stop."""


BRIDGE_STATUS = 'activesurv/stage_bridge/{}'  # the name each bridge's diagnostics carry


def bridges(hw: Hardware) -> list[str]:
    """The stage ids of the rig's bridges: cameras with stages, and the table if it has one."""
    ids = [cid for cid, cam in hw.cameras.items() if cam.stages is not None]
    return ids + ([TABLE_ID] if hw.table is not None else [])


@dataclass
class Confirmations:
    """What each bridge last said (``estop``, ``standing_still``), keyed by stage id."""

    namespace: str
    wanted: set[str]
    said: dict[str, dict[str, str]] = field(default_factory=dict)

    def hear(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            for sid in self.wanted:
                if status.name != BRIDGE_STATUS.format(sid):
                    continue
                values = {kv.key: kv.value for kv in status.values}
                if values.get('namespace', '/').strip('/') == self.namespace.strip('/'):
                    self.said[sid] = values

    def missing(self, raised: bool) -> list[str]:
        """Bridges that have not confirmed yet."""
        want = 'true' if raised else 'false'
        return sorted(
            sid
            for sid in self.wanted
            if not (
                self.said.get(sid, {}).get('estop') == want
                and (not raised or self.said[sid].get('standing_still') == 'true')
            )
        )


def run_stop(
    hw: Hardware, release: bool, timeout: float, progress: Callable[[str], None]
) -> float:
    """Raise (or lower) the rig's e-stop and wait for every bridge to confirm.

    Returns:
        Seconds from the e-stop's publication to the last confirmation.

    Raises:
        EstopError: when a bridge did not confirm within ``timeout`` (naming it).
    """
    wanted = bridges(hw)
    if not wanted:
        raise EstopError(f'{hw.path}: the rig has no stage controllers to stop')
    owns = not rclpy.ok()
    if owns:
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = Node('activesurv_stop')
    heard = Confirmations(hw.namespace, set(wanted))
    try:
        node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS, heard.hear, qos.DIAGNOSTICS)
        pub = node.create_publisher(Bool, hw.topic(topics.ESTOP), qos.ESTOP)
        raised = not release
        t0 = time.monotonic()
        pub.publish(Bool(data=raised))
        what = 'raised' if raised else 'lowered'
        progress(f'e-stop {what} on {hw.topic(topics.ESTOP)}; waiting for {", ".join(wanted)}')
        deadline = t0 + timeout
        while missing := heard.missing(raised):
            if time.monotonic() > deadline:
                raise EstopError(
                    f'no confirmation in {timeout:g} s from {", ".join(missing)} (not running, '
                    f'another ROS domain or namespace than {hw.namespace or "(none)"}, or its '
                    'controller does not answer)'
                )
            rclpy.spin_once(node, timeout_sec=0.05)
        took = time.monotonic() - t0
        state = 'standing still, goals refused' if raised else 'accepting goals'
        progress(f'every bridge confirmed in {took:.2f} s: {state}')
        # Keep the latched message a moment for late subscribers of this namespace.
        end = time.monotonic() + 0.3
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        return took
    finally:
        node.destroy_node()  # type: ignore[no-untyped-call]
        if owns:
            rclpy.try_shutdown()
