"""Camera calibration with OpenCV (the modern equivalent of Tsai's method the paper uses).

* Intrinsics from several views of a checkerboard (``cv2.calibrateCamera``).
* Extrinsics from one view of a board whose world pose is known (``cv2.solvePnP``).
* The mount's offset and pitch from extrinsics taken at known stage positions.

Boards are described by their number of squares (columns, rows) and the square side; OpenCV
works with the inner corners, (columns - 1) x (rows - 1). The board frame has its origin at the
board centre, x along the columns, y along the rows, and z pointing away from the side the
cameras see (OpenCV's convention; in :meth:`activesurv_sim.render.Plate.checkerboard` that
is the plate's ``normal``, with ``x_axis`` the board's x; the square at column 0, row 0 is dark).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import Transform
from activesurv_common.mount import R0, CameraMount
from activesurv_imaging.detect import as_gray8
from activesurv_imaging.errors import CalibrationError

Array = NDArray[np.float64]


def board_points(squares: tuple[int, int], square_size: float) -> Array:
    """Inner-corner positions (N, 3) in the board frame, in OpenCV's row-major order."""
    cols, rows = squares
    if cols < 3 or rows < 3 or not square_size > 0:
        raise CalibrationError(f'a board needs >= 3x3 squares and a positive size, got {squares}')
    i, j = np.meshgrid(np.arange(1, cols), np.arange(1, rows))
    a = (i.ravel() - cols / 2.0) * square_size
    b = (j.ravel() - rows / 2.0) * square_size
    return np.column_stack([a, b, np.zeros_like(a)])


HALF_WINDOW = 0.45  # of a square: the refinement window's half-width (5-15 px)


def refine_corners(image: ArrayLike, corners: ArrayLike) -> Array:
    """``corners`` (N, 2, row-major on the board) refined to sub-pixel in ``image``, in their
    order."""
    img = as_gray8(image)
    rough = np.asarray(corners, dtype=np.float32).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    # The refinement window spans most of a square: a corner blurred by the depth of field (a
    # board nearer or farther than the focus) has its saddle spread over more than the usual
    # 11 x 11 pixels. Measured (offline commissioning, f/4, perturbed rig 3): reprojection RMS
    # 0.27-0.49 -> 0.11-0.19 px, principal point 9-14 -> 1-3 px off; no change on sharp views.
    square_px = float(np.median(np.linalg.norm(np.diff(rough.reshape(-1, 2), axis=0), axis=1)))
    half = int(np.clip(round(HALF_WINDOW * square_px), 5, 15))
    out = cv2.cornerSubPix(img, rough.copy(), (half, half), (-1, -1), criteria)
    return np.asarray(out.reshape(-1, 2), dtype=np.float64)


def find_corners(image: ArrayLike, squares: tuple[int, int]) -> Array | None:
    """Sub-pixel inner corners in the order of :func:`board_points`, or None if not found."""
    img = as_gray8(image)
    pattern = (squares[0] - 1, squares[1] - 1)
    found, corners = cv2.findChessboardCorners(
        img, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    )
    if not found:
        return None
    pts = refine_corners(img, corners.reshape(-1, 2))
    # OpenCV may start from either end of the board (a 180 degree turn). The square diagonally
    # outside the first corner is square (0, 0), which is dark: check, and reverse if not.
    cols = pattern[0]
    step_a = pts[1] - pts[0]
    step_b = pts[cols] - pts[0]
    probe = pts[0] - 0.5 * step_a - 0.5 * step_b
    x, y = round(probe[0]), round(probe[1])
    if 0 <= x < img.shape[1] and 0 <= y < img.shape[0]:
        far = pts[-1] + 0.5 * (pts[-1] - pts[-2]) + 0.5 * (pts[-1] - pts[-1 - cols])
        fx, fy = round(far[0]), round(far[1])
        if 0 <= fx < img.shape[1] and 0 <= fy < img.shape[0] and img[y, x] > img[fy, fx]:
            pts = pts[::-1].copy()
    return pts


def calibrate_intrinsics(
    images: Sequence[ArrayLike],
    squares: tuple[int, int],
    square_size: float,
    name: str = 'camera',
    radial_terms: int = 1,
) -> tuple[CameraModel, float]:
    """Intrinsics and distortion from views of a checkerboard.

    The paper's 25 mm lens on a 1/4-inch sensor sees only about 7 degrees: there ``k2`` and
    ``k3`` trade off against the focal length and come out as nonsense, so only ``k1`` is
    estimated by default (``radial_terms=1``; 2 or 3 for wider lenses such as the overhead
    camera's). Tilt the board by 20-40 degrees in several directions.

    Returns:
        (camera model, RMS reprojection error in pixels).

    Raises:
        CalibrationError: if fewer than 3 images show the whole board.
    """
    obj = board_points(squares, square_size).astype(np.float32)
    object_points, image_points = [], []
    size: tuple[int, int] | None = None
    for image in images:
        img = as_gray8(image)
        size = (img.shape[1], img.shape[0])
        corners = find_corners(img, squares)
        if corners is not None:
            object_points.append(obj)
            image_points.append(corners.astype(np.float32).reshape(-1, 1, 2))
    if len(image_points) < 3 or size is None:
        raise CalibrationError(
            f'the board was found in {len(image_points)} of {len(images)} images; need >= 3'
        )
    if radial_terms not in (1, 2, 3):
        raise CalibrationError(f'radial_terms must be 1, 2 or 3, got {radial_terms}')
    flags = {1: cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3, 2: cv2.CALIB_FIX_K3, 3: 0}[radial_terms]
    rms, K, dist, _, _ = cv2.calibrateCamera(
        object_points, image_points, size, None, None, flags=flags
    )
    K_arr = np.asarray(K, dtype=np.float64)
    dist_arr = np.asarray(dist, dtype=np.float64).reshape(-1)[:5]
    return CameraModel(size[0], size[1], K_arr, dist_arr, name), float(rms)


def board_pose(
    image: ArrayLike, camera: CameraModel, squares: tuple[int, int], square_size: float
) -> Transform:
    """``T_camera_board`` from one view of the board.

    Raises:
        CalibrationError: if the board is not found or the pose cannot be solved.
    """
    corners = find_corners(image, squares)
    if corners is None:
        raise CalibrationError('the calibration board is not (fully) visible in the image')
    ok, rvec, tvec = cv2.solvePnP(
        board_points(squares, square_size),
        corners,
        camera.K,
        camera.dist,
        flags=cv2.SOLVEPNP_ITERATIVE,
    )
    if not ok:
        raise CalibrationError('solvePnP failed for the board view')
    R, _ = cv2.Rodrigues(rvec)
    return Transform(np.asarray(R, dtype=np.float64), tvec.reshape(3).astype(np.float64))


def camera_extrinsics(T_world_board: Transform, T_camera_board: Transform) -> Transform:
    """``T_world_camera`` from the board's known world pose and its pose in the camera."""
    return T_world_board.compose(T_camera_board.inverse())


def mount_from_extrinsics(
    nominal: CameraMount, T_world_camera: Transform, linear: float, yaw: float
) -> CameraMount:
    """The mount's camera offset and pitch from extrinsics measured at joint positions.

    The platform pose at (linear, yaw) comes from the nominal mount (base, axes, yaw offset);
    what is left, ``T_platform_camera``, gives the offset and the pitch.
    """
    T_pc = nominal.platform_pose(linear, yaw).inverse().compose(T_world_camera)
    M = T_pc.R @ R0.T  # = Ry(pitch) ideally
    pitch = math.atan2(M[0, 2], M[0, 0])
    return CameraMount(
        nominal.camera_id,
        nominal.base,
        nominal.yaw_offset,
        pitch,
        T_pc.t,
        nominal.linear_axis,
        nominal.linear_joint,
        nominal.rotary_joint,
    )
