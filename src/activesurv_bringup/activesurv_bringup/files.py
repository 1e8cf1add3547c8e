"""Where bringup's files are: its shipped ``config/``, the cache, and new output directories.

Output directories are never deleted or overwritten: a directory that already holds files is
refused, and commands without an explicit ``--out`` make a new timestamped one, as ``ros2 bag
record`` does.
"""

from __future__ import annotations

import os
from datetime import datetime
from pathlib import Path

from activesurv_bringup.errors import ConfigError


def config_file(name: str) -> Path:
    """A file of this package's ``config/`` (source tree, or the colcon install's share)."""
    here = Path(__file__).resolve().parent
    for candidate in (here.parent / 'config' / name, here / 'data' / name):
        if candidate.exists():
            return candidate
    try:  # only a colcon install has an ament index (optional dependency)
        from ament_index_python.packages import get_package_share_directory

        shared = Path(get_package_share_directory('activesurv_bringup')) / 'config' / name
    except (ImportError, LookupError, OSError) as exc:
        raise ConfigError(f'cannot find config/{name}') from exc
    if not shared.exists():
        raise ConfigError(f'cannot find config/{name}')
    return shared


def config_path() -> Path:
    return config_file('experiments.yaml')


DDS_PROFILES = {'large-images': 'fastdds_large_images.xml'}


def dds_profile_path(name_or_path: str) -> Path:
    """A Fast DDS XML profile: a shipped one by name (``large-images``) or a file path."""
    if name_or_path in DDS_PROFILES:
        return config_file(DDS_PROFILES[name_or_path])
    path = Path(name_or_path)
    if not path.is_file():
        raise ConfigError(
            f'DDS profile {name_or_path!r} is neither a file nor one of {sorted(DDS_PROFILES)}'
        )
    return path.resolve()


def cache_dir() -> Path:
    base = os.environ.get('ACTIVESURV_CACHE') or os.path.join(
        os.environ.get('XDG_CACHE_HOME') or os.path.expanduser('~/.cache'), 'activesurv'
    )
    return Path(base)


def new_output_dir(out: Path) -> Path:
    """``out``, created; refused if it already holds anything (nothing is ever overwritten).

    Raises:
        ConfigError: if ``out`` is a file or a non-empty directory.
    """
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(
            f'{out} already exists and is not empty: give a new --out directory '
            '(nothing is overwritten)'
        )
    out.mkdir(parents=True, exist_ok=True)
    return out


def timestamped_dir(parent: Path, prefix: str, now: datetime | None = None) -> Path:
    """A new directory ``parent/<prefix>_YYYY_MM_DD-HH_MM_SS`` (a suffix if that exists)."""
    stamp = (now or datetime.now()).strftime('%Y_%m_%d-%H_%M_%S')
    path = parent / f'{prefix}_{stamp}'
    n = 1
    while path.exists():
        path = parent / f'{prefix}_{stamp}_{n}'
        n += 1
    path.mkdir(parents=True)
    return path
