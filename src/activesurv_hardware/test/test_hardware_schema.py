"""The hardware file's schema: typical mistakes are each refused with their key path, all at
once; the template and the lab's files pass; the JSON Schema export is a valid schema."""

from __future__ import annotations

import copy
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from activesurv_common.object_geometry import ObjectGeometry
from activesurv_hardware.hardware_file import (
    TemplateRig,
    load_hardware,
    template_text,
)
from activesurv_hardware.schema import (
    HardwareFile,
    hardware_problems,
    json_schema,
    layout_problems,
)

LAYOUT = {
    'cam1': ('cam1_x', 'cam1_yaw'),
    'cam2': ('cam2_yaw',),
    'cam3': ('cam3_yaw',),
    'cam4': ('cam4_x', 'cam4_yaw'),
}


def _template() -> dict[str, Any]:
    rig = TemplateRig(
        'lab',
        '',
        (0.0, 0.5),
        (0.0, 0.2),
        ObjectGeometry(0.06, (0.0, -0.03, -0.02), (0.0, -1.0, 0.0)),
        [
            ('cam1', [('cam1_x', 'linear', 0.0, 0.3), ('cam1_yaw', 'rotary', -1.0, 1.0)]),
            ('cam2', [('cam2_yaw', 'rotary', -1.0, 1.0)]),
            ('cam3', [('cam3_yaw', 'rotary', -1.0, 1.0)]),
            ('cam4', [('cam4_x', 'linear', 0.0, 0.3), ('cam4_yaw', 'rotary', -1.0, 1.0)]),
        ],
        (0.3, 1.2),
        (0.5, 2.0),
    )
    doc = yaml.safe_load(template_text(rig))
    assert isinstance(doc, dict)
    return doc


def _set(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    def edit(doc: dict[str, Any]) -> None:
        *parents, last = path.split('.')
        d: Any = doc
        for p in parents:
            d = d[int(p)] if isinstance(d, list) else d[p]
        if isinstance(d, list):
            d[int(last)] = value
        else:
            d[last] = value

    return edit


def _rename(path: str, new: str) -> Callable[[dict[str, Any]], None]:
    def edit(doc: dict[str, Any]) -> None:
        *parents, last = path.split('.')
        d: Any = doc
        for p in parents:
            d = d[int(p)] if isinstance(d, list) else d[p]
        d[new] = d.pop(last)

    return edit


def _drop(path: str) -> Callable[[dict[str, Any]], None]:
    def edit(doc: dict[str, Any]) -> None:
        *parents, last = path.split('.')
        d: Any = doc
        for p in parents:
            d = d[int(p)] if isinstance(d, list) else d[p]
        del d[last]

    return edit


def _same_port(doc: dict[str, Any]) -> None:
    doc['table']['stages']['controller']['port'] = '/dev/ttyUSB0'  # cam1's Zaber chain


def _two_chains_one_device(doc: dict[str, Any]) -> None:
    doc['cameras']['cam2']['stages']['controller']['port'] = '/dev/ttyUSB0'  # cam1's chain


def _software_device_with_service(doc: dict[str, Any]) -> None:
    cam = doc['cameras']['cam2']
    cam['source'] = {'device': '/dev/video2'}
    cam['trigger'], cam['trigger_service'] = 'software', '/cam2/trigger'


MISTAKES = [
    # (what a lab engineer got wrong, the edit, the key path in the message, a word of it)
    ('typo in a camera key', _rename('cameras.cam1.exposure_delay', 'exposure_dealy'),
     'cameras.cam1.exposure_dealy', 'did you mean exposure_delay?'),
    ('typo in an axis key', _rename('cameras.cam2.stages.axes.0.kind', 'knd'),
     'cameras.cam2.stages.axes[0].knd', 'did you mean kind?'),
    ('typo in a section', _rename('table', 'tabel'), 'tabel', 'did you mean table?'),
    ('unknown protocol', _set('cameras.cam1.stages.controller.protocol', 'zabre'),
     'cameras.cam1.stages.controller.protocol', "'zaber' or 'grbl'"),
    ('unknown trigger', _set('cameras.cam3.trigger', 'sometimes'), 'cameras.cam3.trigger',
     "'hardware', 'software' or 'free'"),
    ('missing trigger', _drop('cameras.cam1.trigger'), 'cameras.cam1.trigger', 'required'),
    ('missing exposure delay', _drop('overhead.exposure_delay'), 'overhead.exposure_delay',
     'required'),
    ('missing axis kind', _drop('cameras.cam4.stages.axes.1.kind'),
     'cameras.cam4.stages.axes[1].kind', 'required'),
    ('baud typo', _set('cameras.cam2.stages.controller.baud', 11520),
     'cameras.cam2.stages.controller.baud', 'standard baud rate'),
    ('negative frame rate', _set('cameras.cam1.frame_rate', -30), 'cameras.cam1.frame_rate',
     '[Hz]'),
    ('delay in ms, not s', _set('cameras.cam1.exposure_delay', 20), 'cameras.cam1.exposure_delay',
     '[s]'),
    ('NaN in a limit', _set('cameras.cam1.stages.axes.0.max', float('nan')),
     'cameras.cam1.stages.axes[0].max', 'finite'),
    ('limits swapped', _set('cameras.cam1.stages.axes.0.min', 0.5),
     'cameras.cam1.stages.axes[0]', 'min < max'),
    ('zero step size', _set('cameras.cam4.stages.axes.0.si_per_unit', 0),
     'cameras.cam4.stages.axes[0].si_per_unit', 'non-zero'),
    ('a Zaber axis given a GRBL letter', _set('cameras.cam3.stages.axes.0.axis', 'X'),
     'cameras.cam3.stages', 'Zaber device number'),
    ('a GRBL axis given a number', _set('table.stages.axes.1.axis', '2'), 'table.stages',
     'GRBL axis letter'),
    ('table without a table joint', _set('table.stages.axes.1.joint', 'table_z'),
     'table.stages', "['table_x', 'table_y']"),
    ('source with neither topic nor device', _set('cameras.cam2.source', {}),
     'cameras.cam2.source', 'exactly one'),
    ('source with both', _set('cameras.cam2.source', {'topic': '/a', 'device': 0}),
     'cameras.cam2.source', 'exactly one'),
    ('table travel reversed', _set('geometry.table.x', [0.5, 0.0]), 'geometry.table.x',
     'min < max'),
    ('normal not unit', _set('geometry.object.side_normal', [0, -2, 0]),
     'geometry.object.side_normal', 'unit vector'),
    ('old board keys', _set('geometry.board', {'columns': 9, 'rows': 6, 'square': 0.006}),
     'geometry.board.columns', 'unknown key'),
    ('camera without stages', _drop('cameras.cam3.stages'), 'cameras.cam3.stages', 'missing'),
    ('two controllers on one port', _same_port, 'table.stages', 'one port /dev/ttyUSB0'),
    ('two cameras, one device number on a chain', _two_chains_one_device,
     'cameras.cam2.stages.axes[0].axis', 'device 1 on /dev/ttyUSB0'),
    ('bad namespace', _set('namespace', 'my lab'), 'namespace', 'letters, digits'),
    ('software trigger of a driver without its service', _set('cameras.cam1.trigger',
     'software'), 'cameras.cam1.trigger_service', 'missing'),
    ('a service named for our own camera node', _software_device_with_service,
     'cameras.cam2.trigger_service', 'only for'),
]  # fmt: skip


@pytest.mark.parametrize(
    ('edit', 'where', 'word'),
    [m[1:] for m in MISTAKES],
    ids=[m[0] for m in MISTAKES],
)
def test_a_mistake_is_refused_with_its_key_path(
    tmp_path: Path, edit: Callable[[dict[str, Any]], None], where: str, word: str
) -> None:
    doc = _template()
    edit(doc)
    model, found = hardware_problems(doc, tmp_path)
    assert model is None
    assert any(line.startswith(f'{where}') and word in line for line in found), found


def test_there_are_at_least_twenty_typical_mistakes() -> None:
    assert len(MISTAKES) >= 20


def test_every_mistake_is_reported_at_once(tmp_path: Path) -> None:
    doc = _template()
    for _, edit, _, _ in MISTAKES[:12]:
        edit(doc)
    _, found = hardware_problems(doc, tmp_path)
    assert len(found) >= 10, found


def test_the_template_passes_and_a_renamed_camera_is_caught_by_the_layout(
    tmp_path: Path,
) -> None:
    doc = _template()
    model, found = hardware_problems(copy.deepcopy(doc), tmp_path)
    assert found == []
    assert model is not None
    assert layout_problems(model, LAYOUT) == []
    doc['cameras']['cam5'] = doc['cameras'].pop('cam4')
    model, found = hardware_problems(doc, tmp_path)
    assert model is not None, found
    lines = layout_problems(model, LAYOUT)
    assert any(ln.startswith('cameras.cam4: missing') and 'cam5' in ln for ln in lines), lines
    assert any(ln.startswith('cameras.cam5: not a camera of the layout') for ln in lines)
    doc = _template()
    doc['cameras']['cam2']['stages']['axes'][0]['joint'] = 'cam2_yew'
    model, _ = hardware_problems(doc, tmp_path)
    assert model is not None
    lines = layout_problems(model, LAYOUT)
    assert any(ln.startswith('cameras.cam2.stages.axes[0].joint: cam2_yew') for ln in lines)


def test_stages_may_be_a_path_and_its_mistakes_are_found_there(tmp_path: Path) -> None:
    doc = _template()
    ctrl = doc['cameras']['cam1']['stages']
    ctrl['controller']['protocol'] = 'zabre'
    (tmp_path / 'cam1.yaml').write_text(yaml.safe_dump(ctrl))
    doc['cameras']['cam1']['stages'] = 'cam1.yaml'
    _, found = hardware_problems(doc, tmp_path)
    assert any(ln.startswith('cameras.cam1.stages.controller.protocol') for ln in found), found
    doc['cameras']['cam1']['stages'] = 'nowhere.yaml'
    _, found = hardware_problems(doc, tmp_path)
    assert any(ln.startswith('cameras.cam1.stages: cannot read') for ln in found), found


def test_the_template_loads_with_its_board_and_home(tmp_path: Path) -> None:
    path = tmp_path / 'hw.yaml'
    path.write_text(yaml.safe_dump(_template()))
    hw = load_hardware(path)
    assert hw.geometry.board.squares == (9, 7)
    assert hw.geometry.board.square_size == pytest.approx(0.004)
    assert hw.home is False
    assert hw.cameras['cam1'].trigger == 'free'


def test_json_schema_export() -> None:
    schema = json_schema()
    text = json.dumps(schema)
    assert schema['title'] == 'activesurv hardware file'
    assert 'exposure_delay' in text
    assert 'additionalProperties' in text
    props = schema['$defs']['CameraSection']['properties']
    assert set(props['trigger'].keys()) & {'$ref', 'allOf', 'anyOf'}
    assert {'type': 'string'}.items() <= props['stages']['anyOf'][-1].items()
    assert HardwareFile.model_json_schema()  # pydantic's own export works


def test_a_device_source_is_software_triggered_through_our_camera_node(tmp_path: Path) -> None:
    doc = _template()
    doc['cameras']['cam2']['source'] = {'device': '/dev/video2'}
    doc['cameras']['cam2']['trigger'] = 'software'
    doc['cameras']['cam2']['frame_rate'] = 25.0
    doc['cameras']['cam3']['source'] = {'topic': '/cam3/image_raw'}
    doc['cameras']['cam3']['trigger'] = 'software'
    doc['cameras']['cam3']['trigger_service'] = '/cam3/driver/trigger'
    doc['cameras']['cam3']['trigger_lead'] = 0.004
    path = tmp_path / 'hw.yaml'
    path.write_text(yaml.safe_dump(doc))
    hw = load_hardware(path)
    # Our node's own service, called half a period ahead; a driver's as the file says.
    assert hw.cameras['cam2'].software_trigger == ('cam2_camera/trigger', pytest.approx(0.02))
    assert hw.cameras['cam3'].software_trigger == ('/cam3/driver/trigger', 0.004)
    assert hw.cameras['cam1'].software_trigger == ('', 0.0)
