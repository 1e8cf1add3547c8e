"""Conversions shared by every node: stamps, camera info, images, states, poses, mounts.

Each function turns a message (or node parameters) into a core value or back; none keeps
state (:class:`CameraInfoStamper` keeps one camera's message, to stamp copies of it). The
package-specific ones (plans, observations, estimates) live in each package's own
``conversions.py``.
"""

from __future__ import annotations

import array
import copy
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Pose, TransformStamped
from rcl_interfaces.msg import ParameterDescriptor
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header

from activesurv_common.camera_model import CameraModel
from activesurv_common.errors import CalibrationError
from activesurv_common.geometry import Transform, matrix_from_quaternion
from activesurv_common.images import to_gray
from activesurv_common.mount import CameraMount
from activesurv_interfaces.msg import ObjectState

NAN3 = (math.nan, math.nan, math.nan)


def time_to_sec(stamp: Time) -> float:
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


def sec_to_time(t: float) -> Time:
    if not math.isfinite(t) or t < 0.0:
        return Time()
    sec = math.floor(t)
    return Time(sec=sec, nanosec=min(round((t - sec) * 1e9), 999_999_999))


# -- camera info and images ----------------------------------------------------------------
def camera_info_from_model(model: CameraModel, frame_id: str, stamp: Time) -> CameraInfo:
    msg = CameraInfo()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.width, msg.height = model.width, model.height
    msg.distortion_model = 'plumb_bob'
    msg.d = [float(v) for v in model.dist[:5]]
    msg.k = [float(v) for v in model.K.reshape(-1)]
    msg.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    P = np.zeros((3, 4))
    P[:, :3] = model.K
    msg.p = [float(v) for v in P.reshape(-1)]
    return msg


class CameraInfoStamper:
    """A camera's ``CameraInfo`` built once; each frame gets a copy with its own header.

    A frame's intrinsics go out beside it at a demand instant, where building the message anew
    (its four matrices, field by field) took 0.2 ms of CPU per camera (docs/performance.md).
    The copies share the template's arrays: like every published message, read, never changed.
    """

    def __init__(self, model: CameraModel, frame_id: str) -> None:
        self._template = camera_info_from_model(model, frame_id, Time())

    def __call__(self, stamp: Time) -> CameraInfo:
        msg = copy.copy(self._template)
        msg.header = Header(stamp=stamp, frame_id=self._template.header.frame_id)
        return msg


def model_from_camera_info(msg: CameraInfo, name: str) -> CameraModel:
    """Intrinsics from a CameraInfo (plumb_bob or no distortion).

    Raises:
        CalibrationError: for an empty or inconsistent CameraInfo.
    """
    if msg.distortion_model not in ('plumb_bob', 'rational_polynomial', ''):
        raise CalibrationError(f'{name}: unsupported distortion model {msg.distortion_model}')
    return CameraModel(
        int(msg.width),
        int(msg.height),
        np.array(msg.k).reshape(3, 3),
        np.array(msg.d[:5]) if len(msg.d) else np.zeros(5),
        name,
    )


def image_to_gray(msg: Image) -> np.ndarray:
    """An 8-bit grey array from an image of any encoding camera drivers publish
    (:data:`activesurv_common.images.ENCODINGS`: mono8/16, rgb8/bgr8/rgba8/bgra8, bayer_*,
    yuv422).

    Raises:
        ImageFormatError: for other encodings or a buffer that does not match the header.
    """
    return to_gray(
        bytes(msg.data),
        int(msg.width),
        int(msg.height),
        int(msg.step),
        str(msg.encoding),
        bool(msg.is_bigendian),
    )


def gray_to_image(gray: np.ndarray, frame_id: str, stamp: Time) -> Image:
    # The pixels copied once, into the message's own array: a checking message keeps the
    # array it is given, an unchecking one copies it again (on a frame's critical path).
    msg = Image(check_fields=True)
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height, msg.width = int(gray.shape[0]), int(gray.shape[1])
    msg.encoding = 'mono8'
    msg.is_bigendian = 0
    msg.step = msg.width
    data = array.array('B')
    data.frombytes(np.ascontiguousarray(gray, dtype=np.uint8).data)
    msg.data = data
    return msg


# -- states ------------------------------------------------------------------------------
def object_state_vector(msg: ObjectState) -> np.ndarray:
    """(top marker xyz, side marker xyz, side normal xyz) as one 9-vector."""
    t, s, n = msg.top_marker, msg.side_marker, msg.side_normal
    return np.array([t.x, t.y, t.z, s.x, s.y, s.z, n.x, n.y, n.z], dtype=np.float64)


def joint_vector(
    msg: JointState, names: Sequence[str], field: str = 'position'
) -> np.ndarray | None:
    """Positions (or ``field='velocity'``: rates) of ``names``, in that order, from a
    JointState; None if one is missing."""
    table = dict(zip(msg.name, getattr(msg, field), strict=False))
    try:
        return np.array([float(table[n]) for n in names], dtype=np.float64)
    except KeyError:
        return None


def transform_stamped(parent: str, child: str, T: Transform, stamp: Time) -> TransformStamped:
    """A tf edge ``parent -> child`` (``T`` maps child coordinates into the parent)."""
    msg = TransformStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = parent
    msg.child_frame_id = child
    tr = msg.transform.translation
    tr.x, tr.y, tr.z = (float(v) for v in T.t)
    q = msg.transform.rotation
    q.x, q.y, q.z, q.w = (float(v) for v in T.quaternion())
    return msg


def pose_from_transform(T: Transform) -> Pose:
    p = Pose()
    p.position.x, p.position.y, p.position.z = (float(v) for v in T.t)
    q = T.quaternion()
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = (float(v) for v in q)
    return p


def transform_from_pose(p: Pose) -> Transform:
    """The transform of a ``geometry_msgs/Pose`` (the inverse of :func:`pose_from_transform`).

    Raises:
        GeometryError: for a non-finite position or a zero quaternion.
    """
    q = (p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w)
    return Transform.from_rt(matrix_from_quaternion(q), (p.position.x, p.position.y, p.position.z))


def vector3(v: Any) -> np.ndarray:
    """A ``geometry_msgs`` Point or Vector3 as a (3,) float array (NaN passes through)."""
    return np.array([v.x, v.y, v.z], dtype=np.float64)


# -- mount parameters ----------------------------------------------------------------------
MOUNT_PARAMETERS: dict[str, tuple[Any, str]] = {
    'mount.base': ([0.0, 0.0, 0.0], 'world position of the rotation axis at linear 0 (m)'),
    'mount.yaw_offset': (0.0, 'world yaw of the optical axis at rotary 0 (rad)'),
    'mount.pitch': (0.0, 'downward tilt of the optical axis (rad)'),
    'mount.offset': ([0.0, 0.0, 0.0], 'camera centre from the rotation axis, platform frame (m)'),
    'mount.linear_axis': ([0.0, 0.0, 0.0], 'world direction of the linear stage; zeros: none'),
    'mount.static_pose': ([0.0] * 7, 'x,y,z,qx,qy,qz,qw of a static camera; zeros: use stages'),
}


def declare_mount_parameters(node: Any) -> None:
    for name, (default, text) in MOUNT_PARAMETERS.items():
        node.declare_parameter(name, default, ParameterDescriptor(description=text))


def mount_from_parameters(camera_id: str, values: dict[str, Any]) -> CameraMount | Transform:
    """A stage mount, or the fixed ``T_world_camera`` of a static camera.

    Raises:
        CalibrationError: for malformed values.
    """
    try:
        static = [float(v) for v in values['mount.static_pose']]
        if len(static) != 7:
            raise CalibrationError(f'{camera_id}: mount.static_pose needs 7 numbers')
        if any(static):
            return Transform.from_rt(matrix_from_quaternion(static[3:]), static[:3])
        axis = [float(v) for v in values['mount.linear_axis']]
        return CameraMount(
            camera_id,
            np.array(values['mount.base'], dtype=float),
            float(values['mount.yaw_offset']),
            float(values['mount.pitch']),
            np.array(values['mount.offset'], dtype=float),
            np.array(axis) if any(axis) else None,
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise CalibrationError(f'{camera_id}: malformed mount parameters: {exc}') from exc
