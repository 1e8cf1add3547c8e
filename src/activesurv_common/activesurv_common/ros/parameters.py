"""Node parameters the rclpy way: declared with typed defaults and descriptors, checked on set.

A node lists its parameters as :class:`Param` values and calls :func:`declare`. The on-set
callback is registered *before* the parameters are declared, so rclpy runs it on the values given
at start-up (``-p``, ``--params-file``) as on every later ``ros2 param set``: a bad value fails
the node's construction with ``InvalidParameterValueException`` naming the parameter and the
reason, and :func:`activesurv_common.ros.node.run_node` turns that into one line on stderr.
Numeric bounds also go into the descriptor's range, so ``ros2 param describe`` shows them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

Check = Callable[[Any], str | None]
"""Extra check of one value: returns why it is wrong, or None when it is fine."""


@dataclass(frozen=True)
class Param:
    """One parameter of a node.

    Attributes:
        name: parameter name.
        default: typed default value, or a ``Parameter.Type`` for a parameter left unset.
        description: what it is, with its unit.
        minimum: inclusive lower bound of a number.
        above: exclusive lower bound of a number (``above=0.0``: must be > 0).
        maximum: inclusive upper bound of a number.
        choices: the allowed strings.
        check: any further check.
        read_only: fixed once the node has started.
    """

    name: str
    default: Any
    description: str
    minimum: float | None = None
    above: float | None = None
    maximum: float | None = None
    choices: tuple[str, ...] = ()
    check: Check | None = None
    read_only: bool = False

    def descriptor(self) -> ParameterDescriptor:
        text = self.description
        if self.choices:
            text += f' (one of {", ".join(self.choices)})'
        d = ParameterDescriptor(description=text, read_only=self.read_only)
        low = self.minimum if self.minimum is not None else self.above
        if isinstance(self.default, bool) or (low is None and self.maximum is None):
            return d
        if isinstance(self.default, int):
            d.integer_range = [
                IntegerRange(
                    from_value=int(low) if low is not None else -(2**31),
                    to_value=int(self.maximum) if self.maximum is not None else 2**31 - 1,
                    step=0,
                )
            ]
        elif isinstance(self.default, float):
            d.floating_point_range = [
                FloatingPointRange(
                    from_value=float(low) if low is not None else -math.inf,
                    to_value=float(self.maximum) if self.maximum is not None else math.inf,
                    step=0.0,
                )
            ]
        return d

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is not acceptable, or None."""
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            if not math.isfinite(float(value)):
                return f'{self.name} must be finite, got {value}'
            if self.minimum is not None and value < self.minimum:
                return f'{self.name} must be >= {self.minimum:g}, got {value}'
            if self.above is not None and value <= self.above:
                return f'{self.name} must be > {self.above:g}, got {value}'
            if self.maximum is not None and value > self.maximum:
                return f'{self.name} must be <= {self.maximum:g}, got {value}'
        if self.choices and value not in self.choices:
            return f'{self.name} must be one of {", ".join(self.choices)}, got {value!r}'
        if self.check is not None:
            return self.check(value)
        return None


def checker(params: Sequence[Param]) -> Callable[[list[Parameter]], SetParametersResult]:
    """The on-set callback that applies each :class:`Param`'s checks."""
    by_name = {p.name: p for p in params}

    def on_set(changes: list[Parameter]) -> SetParametersResult:
        for change in changes:
            spec = by_name.get(change.name)
            if spec is None or change.value is None:
                continue
            why = spec.problem(change.value)
            if why is not None:
                return SetParametersResult(successful=False, reason=why)
        return SetParametersResult(successful=True)

    return on_set


def declare(node: Node, params: Sequence[Param]) -> None:
    """Register the checks, then declare every parameter (start-up values are checked too)."""
    node.add_on_set_parameters_callback(checker(params))
    for p in params:
        node.declare_parameter(p.name, p.default, p.descriptor())


def values(node: Node, params: Sequence[Param]) -> dict[str, Any]:
    """Current values of ``params`` by name."""
    return {p.name: node.get_parameter(p.name).value for p in params}
