"""`record_of`: a record of options filled from a command's parameters by name."""

from __future__ import annotations

import inspect

import msgspec
import pytest

from vge_analytics.commands._options import record_of
from vge_analytics.commands.run import run_command
from vge_analytics.live import AgentOptions, ClientSettings, RunOptions


class Pair(msgspec.Struct):
    a: int
    b: str = "b"


def test_fields_come_from_the_parameters_or_given() -> None:
    assert record_of(Pair, {"a": 1, "b": "x", "other": 3}) == Pair(1, "x")
    assert record_of(Pair, {"a": 1, "b": "x"}, b="given") == Pair(1, "given")


def test_a_field_with_no_parameter_is_an_error_even_with_a_default() -> None:
    with pytest.raises(TypeError, match="Pair: no parameter for b"):
        record_of(Pair, {"a": 1})


@pytest.mark.parametrize(
    ("record", "given"),
    [(ClientSettings, set()), (AgentOptions, {"client"}), (RunOptions, {"episodes", "continuation"})],
)
def test_vge_run_has_a_parameter_for_every_field(record, given) -> None:
    params = set(inspect.signature(run_command).parameters)
    assert set(record.__struct_fields__) - given <= params
