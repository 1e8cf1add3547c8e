"""Reliability under load (issue 8.7): the graph while every camera streams 640x480 at 30 Hz.

Two graph runs of Set A with the fast system at the default speed (rtf 0.5, seed 7; at rtf 1
this shared 2-core machine cannot render the simulated cameras in time): one plain, one with
an ``image_load`` node streaming 640x480 rgb8 images at 30 Hz for each of the four cameras
(about 110 MB/s through DDS) and a second ``image_load`` node receiving them. Reported: the
estimate latency (simulated time from the demand instant to the fused estimate, median and
90th percentile) with and without the load, and the fraction of stream frames lost (best
effort, like camera drivers). The streams are thinned to 2 Hz in the bag. The loaded run is
made twice: with Fast DDS's builtin transports (the plain keys) and with the shipped profile
``config/fastdds_large_images.xml`` for every node (keys ending ``_large_images``).
"""

from __future__ import annotations

import json
import statistics
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from activesurv_bringup.experiments.experiment import load_experiment
from activesurv_bringup.experiments.graph import run_graph
from activesurv_bringup.experiments.options import RunOptions
from activesurv_bringup.files import dds_profile_path
from activesurv_evaluation.runs import load_run
from activesurv_launch.launcher import NodeSpec
from activesurv_recording.load_node import stream_topic

CAMERAS = ['cam1', 'cam2', 'cam3', 'cam4']
RTF = 0.5


def _latency(doc: dict[str, Any]) -> tuple[float | None, float | None]:
    lat = [d['latency'] for d in doc['demands'] if d['latency'] is not None]
    if not lat:
        return None, None
    return round(1e3 * statistics.median(lat), 1), round(1e3 * float(np.percentile(lat, 90)), 1)


def _loaded_run(
    exp: Any, tmp: Path, name: str, profile: Path | None = None
) -> tuple[dict[str, Any], dict[str, Any]]:
    """One graph run with the four 30 Hz streams next to it: (results, stream counts)."""
    summary_file = tmp / f'{name}.json'
    load = [
        NodeSpec(
            'image_stream',
            'activesurv_recording.load_node',
            parameters={'role': 'stream', 'camera_ids': CAMERAS, 'rate': 30.0},
        ),
        NodeSpec(
            'image_count',
            'activesurv_recording.load_node',
            parameters={'role': 'count', 'camera_ids': CAMERAS, 'summary_file': str(summary_file)},
        ),
    ]
    run_graph(
        exp,
        tmp / name,
        RunOptions(
            rtf=RTF,
            extra=tuple(load),
            thin=tuple(f'/{stream_topic(c)}' for c in CAMERAS),
            dds_profile=profile,
        ),
        progress=lambda _: None,
    )
    return load_run(tmp / name), json.loads(summary_file.read_text())


def _stream_keys(suffix: str, doc: dict[str, Any], counts: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    out[f'latency_ms_30hz{suffix}'], out[f'latency_p90_ms_30hz{suffix}'] = _latency(doc)
    dropped = counts['dropped_fraction']
    out[f'dropped_frames_30hz{suffix}'] = round(float(dropped), 4) if dropped is not None else None
    out[f'stream_frames_30hz{suffix}'] = f'{counts["received"]}/{counts["expected"]}'
    delay = counts['median_delay_ms']
    out[f'stream_delay_ms_30hz{suffix}'] = round(delay, 2) if delay is not None else None
    out[f'estimates_30hz{suffix}'] = sum(
        d['estimated_position'] is not None for d in doc['demands']
    )
    return out


def run() -> dict[str, Any]:
    out: dict[str, Any] = {}
    exp = load_experiment('A', 'fast', 7)
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        run_graph(exp, tmp / 'plain', RunOptions(rtf=RTF), progress=lambda _: None)
        out['latency_ms_plain'], out['latency_p90_ms_plain'] = _latency(load_run(tmp / 'plain'))
        # Out of the box: Fast DDS's builtin transports (512 kB shared-memory segments).
        out.update(_stream_keys('', *_loaded_run(exp, tmp, 'loaded')))
        # With the shipped profile for camera-sized messages (every node of the run uses it).
        profile = dds_profile_path('large-images')
        out.update(
            _stream_keys('_large_images', *_loaded_run(exp, tmp, 'loaded_profile', profile))
        )
    return out
