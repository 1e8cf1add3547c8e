"""Reliability under load (issue 8.7): the graph while every camera streams 640x480 at 30 Hz.

Two graph runs of Set A with the fast system at the default speed (rtf 0.5, seed 7; at rtf 1
this shared 2-core machine cannot render the simulated cameras in time): one plain, one with
an ``image_load`` node streaming 640x480 rgb8 images at 30 Hz for each of the four cameras
(about 110 MB/s through DDS) and a second ``image_load`` node receiving them. Reported: the
estimate latency (simulated time from the demand instant to the fused estimate, median and
90th percentile) with and without the load, and the fraction of stream frames lost (best
effort, like camera drivers). The streams are thinned to 2 Hz in the bag.
"""

from __future__ import annotations

import json
import statistics
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from activesurv_bringup.experiment import load_experiment
from activesurv_bringup.graph import run_graph
from activesurv_bringup.launcher import NodeSpec
from activesurv_bringup.load_node import stream_topic
from activesurv_bringup.report import load_run

CAMERAS = ['cam1', 'cam2', 'cam3', 'cam4']
RTF = 0.5


def _latency(doc: dict[str, Any]) -> tuple[float | None, float | None]:
    lat = [d['latency'] for d in doc['demands'] if d['latency'] is not None]
    if not lat:
        return None, None
    return round(1e3 * statistics.median(lat), 1), round(1e3 * float(np.percentile(lat, 90)), 1)


def run() -> dict[str, Any]:
    out: dict[str, Any] = {}
    exp = load_experiment('A', 'fast', 7)
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / 'plain'
        run_graph(exp, base, rtf=RTF, progress=lambda _: None)
        plain = load_run(base)
        summary_file = Path(tmp) / 'load.json'
        load = [
            NodeSpec(
                'image_stream',
                'activesurv_bringup.load_node',
                parameters={'role': 'stream', 'camera_ids': CAMERAS, 'rate': 30.0},
            ),
            NodeSpec(
                'image_count',
                'activesurv_bringup.load_node',
                parameters={
                    'role': 'count',
                    'camera_ids': CAMERAS,
                    'summary_file': str(summary_file),
                },
            ),
        ]
        loaded_dir = Path(tmp) / 'loaded'
        run_graph(
            exp,
            loaded_dir,
            rtf=RTF,
            progress=lambda _: None,
            extra=load,
            thin=[f'/{stream_topic(c)}' for c in CAMERAS],
        )
        loaded = load_run(loaded_dir)
        counts = json.loads(summary_file.read_text())
    out['latency_ms_plain'], out['latency_p90_ms_plain'] = _latency(plain)
    out['latency_ms_30hz'], out['latency_p90_ms_30hz'] = _latency(loaded)
    out['dropped_frames_30hz'] = (
        round(float(counts['dropped_fraction']), 4)
        if counts['dropped_fraction'] is not None
        else None
    )
    out['stream_frames_30hz'] = f'{counts["received"]}/{counts["expected"]}'
    out['stream_delay_ms_30hz'] = (
        round(counts['median_delay_ms'], 2) if counts['median_delay_ms'] is not None else None
    )
    out['estimates_30hz'] = sum(d['estimated_position'] is not None for d in loaded['demands'])
    return out
