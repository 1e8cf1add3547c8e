"""Decode every message of every bag under a directory with Foxglove's own readers.

    .venv/bin/python scripts/decode_bags.py runs/demo_1

Each ``*.mcap`` below the directory is read with the ``mcap`` package and every message decoded
with ``mcap-ros2-support``'s ``DecoderFactory`` (what Foxglove's Python tooling uses). Prints
per bag the messages decoded, the topics, and the ``/tf`` and ``/tf_static`` counts; exits 1 if
any message fails to decode or no bag is found.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def decode_bag(path: Path) -> Counter[str]:
    """Messages decoded per topic (raises on the first that does not decode)."""
    counts: Counter[str] = Counter()
    with path.open('rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, channel, _message, _decoded in reader.iter_decoded_messages():
            counts[channel.topic] += 1
    return counts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('root', type=Path, help='a directory holding bags (searched recursively)')
    args = parser.parse_args(argv)
    bags = sorted(args.root.rglob('*.mcap'))
    if not bags:
        print(f'no .mcap bag under {args.root}', file=sys.stderr)
        return 1
    total, failed = 0, 0
    for bag in bags:
        try:
            n = decode_bag(bag)
        except Exception as exc:  # report every bag, then fail
            failed += 1
            print(f'{bag.relative_to(args.root)}: FAILED: {exc}')
            continue
        total += sum(n.values())
        print(
            f'{bag.relative_to(args.root)}: {sum(n.values())} messages decoded, {len(n)} topics, '
            f'/tf {n["/tf"]}, /tf_static {n["/tf_static"]}'
        )
    print(f'{len(bags)} bags, {total} messages decoded, {failed} failed')
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
