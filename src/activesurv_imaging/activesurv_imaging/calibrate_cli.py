"""``activesurv_calibrate``: camera calibration commands, results written to YAML.

Subcommands::

    intrinsics      --images 'DIR/*.png' --squares 9x6 --square-size 0.005 --name cam1
                    --out cam1.yaml [--radial-terms 1]
    extrinsics      --image IMG --intrinsics cam1.yaml --squares 9x6 --square-size 0.005
                    --board-pose x,y,z,qx,qy,qz,qw --out cam1_extrinsics.yaml
    rotation-centre --before before.csv --after after.csv --angle-deg A [--pitch-deg P]
                    --out cam1_offset.yaml

``rotation-centre`` is the moving-camera calibration of Appendix C: CSV files of target positions
(x, y, z in metres, camera optical frame, one reading per line, header optional) taken before
and after turning the rotary stage by A degrees with the target fixed. Readings are averaged
(the paper fuses repeated readings) before solving eq. C1.
"""

from __future__ import annotations

import argparse
import glob
import math
import sys
from pathlib import Path

import cv2
import numpy as np
import yaml

from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import Transform, matrix_from_quaternion
from activesurv_common.mount import solve_rotation_centre
from activesurv_imaging.calibration import (
    board_pose,
    calibrate_intrinsics,
    camera_extrinsics,
)
from activesurv_imaging.errors import ImagingError, VisionErrors


def _squares(text: str) -> tuple[int, int]:
    try:
        cols, rows = (int(v) for v in text.lower().split('x'))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f'expected COLSxROWS, e.g. 9x6, got {text!r}') from exc
    return cols, rows


def _floats(n: int):  # type: ignore[no-untyped-def]
    def parse(text: str) -> list[float]:
        vals = [float(v) for v in text.split(',')]
        if len(vals) != n:
            raise argparse.ArgumentTypeError(f'expected {n} comma-separated numbers')
        return vals

    return parse


def _read_image(path: str) -> np.ndarray:
    img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise ImagingError(f'cannot read image {path}')
    return img


def _read_points(path: Path) -> np.ndarray:
    try:
        rows = [line for line in path.read_text().splitlines() if line.strip()]
    except OSError as exc:
        raise ImagingError(f'cannot read {path}: {exc}') from exc
    if rows and not rows[0].lstrip().lstrip('-')[:1].isdigit():
        rows = rows[1:]  # header
    try:
        pts = np.array([[float(v) for v in r.split(',')[:3]] for r in rows])
    except ValueError as exc:
        raise ImagingError(f'{path}: every line must be x,y,z numbers: {exc}') from exc
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
        raise ImagingError(f'{path}: expected lines of x,y,z')
    return pts


def _transform_dict(T: Transform) -> dict[str, list[float]]:
    return {
        'translation': [float(v) for v in T.t],
        'rotation_xyzw': [float(v) for v in T.quaternion()],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog='activesurv_calibrate',
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest='command', required=True)
    p = sub.add_parser('intrinsics', help='intrinsics from checkerboard images')
    p.add_argument('--images', required=True, help='glob of image files')
    p.add_argument('--squares', type=_squares, required=True, help='board squares, COLSxROWS')
    p.add_argument('--square-size', type=float, required=True, help='square side (m)')
    p.add_argument('--name', default='camera')
    p.add_argument('--radial-terms', type=int, default=1, choices=(1, 2, 3))
    p.add_argument('--out', type=Path, required=True)
    p = sub.add_parser('extrinsics', help='camera pose from a board at a known world pose')
    p.add_argument('--image', required=True)
    p.add_argument('--intrinsics', type=Path, required=True)
    p.add_argument('--squares', type=_squares, required=True)
    p.add_argument('--square-size', type=float, required=True)
    p.add_argument(
        '--board-pose',
        type=_floats(7),
        required=True,
        help='board pose in world: x,y,z,qx,qy,qz,qw',
    )
    p.add_argument('--out', type=Path, required=True)
    p = sub.add_parser('rotation-centre', help='rotation-centre offset (Appendix C, eq. C1)')
    p.add_argument('--before', type=Path, required=True)
    p.add_argument('--after', type=Path, required=True)
    p.add_argument('--angle-deg', type=float, required=True)
    p.add_argument('--pitch-deg', type=float, default=0.0)
    p.add_argument('--out', type=Path, required=True)
    args = parser.parse_args(argv)

    try:
        if args.command == 'intrinsics':
            files = sorted(glob.glob(args.images))
            if not files:
                raise ImagingError(f'no images match {args.images}')
            cam, rms = calibrate_intrinsics(
                [_read_image(f) for f in files],
                args.squares,
                args.square_size,
                args.name,
                args.radial_terms,
            )
            cam.save(args.out)
            print(
                f'{args.name}: fx={cam.fx:.1f} fy={cam.fy:.1f} cx={cam.cx:.1f} '
                f'cy={cam.cy:.1f} rms={rms:.3f} px from {len(files)} images -> {args.out}'
            )
        elif args.command == 'extrinsics':
            cam = CameraModel.load(args.intrinsics)
            x, y, z, *q = args.board_pose
            T_wb = Transform(matrix_from_quaternion(q), np.array([x, y, z]))
            T_cb = board_pose(_read_image(args.image), cam, args.squares, args.square_size)
            T_wc = camera_extrinsics(T_wb, T_cb)
            args.out.write_text(
                yaml.safe_dump(
                    {'camera_name': cam.name, 'T_world_camera': _transform_dict(T_wc)},
                    sort_keys=False,
                )
            )
            print(f'{cam.name}: camera at {np.round(T_wc.t, 4).tolist()} m -> {args.out}')
        elif args.command == 'rotation-centre':
            before = _read_points(args.before).mean(axis=0)
            after = _read_points(args.after).mean(axis=0)
            centre = solve_rotation_centre(
                before, after, math.radians(args.angle_deg), math.radians(args.pitch_deg)
            )
            offset = [float(-centre[0]), float(-centre[1])]
            args.out.write_text(
                yaml.safe_dump(
                    {
                        'rotation_centre_camera_xy': [float(v) for v in centre],
                        'camera_offset_platform_xy': offset,
                        'note': 'offset: camera centre from the rotation axis (platform frame, m)',
                    },
                    sort_keys=False,
                )
            )
            print(
                f'rotation centre {np.round(centre, 5).tolist()} m; camera offset '
                f'{np.round(offset, 5).tolist()} m -> {args.out}'
            )
    except (*VisionErrors, OSError) as exc:
        print(f'activesurv_calibrate {args.command}: error: {exc}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
