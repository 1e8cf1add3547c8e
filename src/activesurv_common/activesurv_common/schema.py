"""Validation of the YAML files users write, with pydantic: every mistake at once, one line each.

Each line names the key path (``cameras.cam1.exposure_dealy``) and what is wrong with it; an
unknown key names the nearest valid one (``unknown key (did you mean exposure_delay?)``).
:class:`StrictModel` is the base of every schema: unknown keys are errors, numbers must be
finite (YAML's ``.nan`` and ``.inf`` are refused), models are frozen. Values are read in
pydantic's lax mode (YAML strings for enums; a quoted number is still read as the number).
"""

from __future__ import annotations

import difflib
import types
import typing
from collections.abc import Sequence
from typing import Any, Union

from pydantic import BaseModel, ConfigDict, ValidationError


class StrictModel(BaseModel):
    """A section of a user's YAML file: unknown keys refused, finite numbers, frozen."""

    model_config = ConfigDict(extra='forbid', allow_inf_nan=False, frozen=True)


def _unwrap(annotation: Any) -> list[Any]:
    """The model or container types an annotation may hold (Optional/Union/Annotated opened)."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _unwrap(typing.get_args(annotation)[0])
    if origin in (Union, types.UnionType):
        return [t for a in typing.get_args(annotation) for t in _unwrap(a)]
    return [annotation]


def _model_at(root: type[BaseModel], loc: Sequence[int | str]) -> type[BaseModel] | None:
    """The model class that holds the key at ``loc`` (its last element), if one does."""
    current: list[Any] = [root]
    for part in loc[:-1]:
        following: list[Any] = []
        for t in current:
            if isinstance(t, type) and issubclass(t, BaseModel):
                field = t.model_fields.get(str(part))
                if field is not None:
                    following += _unwrap(field.annotation)
                continue
            origin = typing.get_origin(t)
            args = typing.get_args(t)
            if origin in (dict, typing.Mapping) and len(args) == 2:
                following += _unwrap(args[1])
            elif origin in (list, tuple, Sequence) and args and isinstance(part, int):
                following += _unwrap(args[0])
        current = following
    for t in current:
        if isinstance(t, type) and issubclass(t, BaseModel):
            return t
    return None


def key_path(loc: Sequence[int | str], prefix: str = '') -> str:
    """A pydantic location as a key path: ``('axes', 0, 'kind')`` -> ``axes[0].kind``."""
    out = prefix
    for part in loc:
        if isinstance(part, int):
            out += f'[{part}]'
        else:
            out += ('.' if out else '') + str(part)
    return out or '(top level)'


def problems(exc: ValidationError, model: type[BaseModel], prefix: str = '') -> list[str]:
    """One line per mistake of a pydantic validation, each naming its key path."""
    lines = []
    for err in exc.errors(include_url=False):
        loc = tuple(err['loc'])
        where = key_path(loc, prefix)
        kind = err['type']
        if kind == 'extra_forbidden':
            holder = _model_at(model, loc)
            valid = sorted(holder.model_fields) if holder is not None else []
            near = difflib.get_close_matches(str(loc[-1]), valid, n=1, cutoff=0.6)
            hint = f'did you mean {near[0]}?' if near else f'valid keys: {", ".join(valid)}'
            lines.append(f'{where}: unknown key ({hint})')
        elif kind == 'missing':
            lines.append(f'{where}: missing (required)')
        else:
            msg = str(err['msg'])
            msg = msg.removeprefix('Value error, ').removeprefix('Assertion failed, ')
            unit = _unit(model, loc)
            if unit and '[' not in msg:
                msg += f' [{unit}]'
            got = err.get('input')
            shown = '' if isinstance(got, (dict, list)) else f', got {got!r}'
            lines.append(f'{where}: {msg}{shown}')
    return lines


def _unit(model: type[BaseModel], loc: Sequence[int | str]) -> str:
    """The unit a field's description ends with (``... [s]``), or ''."""
    if not loc:
        return ''
    holder = _model_at(model, loc)
    field = holder.model_fields.get(str(loc[-1])) if holder is not None else None
    text = (field.description or '') if field is not None else ''
    if text.endswith(']') and '[' in text:
        return text[text.rindex('[') + 1 : -1]
    return ''
