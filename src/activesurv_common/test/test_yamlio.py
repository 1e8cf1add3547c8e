from __future__ import annotations

import pytest
import yaml

from activesurv_common.sensor_model import default_model_path
from activesurv_common.yamlio import load_yaml


def test_load_yaml_reads_what_safe_load_reads() -> None:
    text = default_model_path().read_text()
    assert load_yaml(text) == yaml.safe_load(text)
    assert load_yaml('a: [1, 2.5, null, yes]\nb: {c: "x"}') == {
        'a': [1, 2.5, None, True],
        'b': {'c': 'x'},
    }


def test_load_yaml_refuses_what_safe_load_refuses() -> None:
    with pytest.raises(yaml.YAMLError):
        load_yaml('a: !!python/object/apply:os.system ["true"]')
    with pytest.raises(yaml.YAMLError):
        load_yaml('a: [1, 2')
