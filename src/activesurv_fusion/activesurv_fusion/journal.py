"""The fusion node's journal: indices of answered demands, one per line, fsynced.

It survives a crash of the node, so a restarted fusion node never answers a demand twice; a
torn last line (a kill in the middle of a write) is ignored.
"""

from __future__ import annotations

import os


def read_journal(path: str) -> set[int]:
    """Indices in the journal; a torn last line (a kill mid-write) is ignored."""
    try:
        with open(path, encoding='utf-8') as f:
            return {int(line) for line in f.read().split('\n') if line.strip().isdigit()}
    except FileNotFoundError:
        return set()


def append_journal(path: str, index: int) -> None:
    with open(path, 'a', encoding='utf-8') as f:
        f.write(f'{index}\n')
        f.flush()
        os.fsync(f.fileno())
