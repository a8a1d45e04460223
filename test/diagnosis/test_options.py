"""The diagnosis's switches: enums with one set of defaults that ``diagnose()`` and
``rheo-shaping diagnose`` share; a wrong value is refused with the choices named."""
from __future__ import annotations

import inspect
from pathlib import Path

import pytest

from rheo_shaping.cli import build_parser
from rheo_shaping.diagnosis import (DEFAULTS, BaselineMode, FloorKind, InitialMode, Options,
                                    diagnose)


def test_the_function_and_the_command_share_one_set_of_defaults():
    sig = inspect.signature(diagnose).parameters
    args = build_parser().parse_args(["diagnose", "some-record"])
    for name in ("initial_state", "floor", "baseline"):
        default = getattr(DEFAULTS, name)
        assert sig[name].default == default, name
        assert getattr(args, name) == str(default), name
    assert DEFAULTS == Options(initial_state=InitialMode.AUTO, floor=FloorKind.MODEL_FORM,
                               baseline=BaselineMode.CALIBRATED)


def test_the_command_offers_each_enum_value():
    sub = build_parser()._subparsers._group_actions[0].choices["diagnose"]
    choices = {a.dest: a.choices for a in sub._actions}
    assert list(choices["initial_state"]) == [m.value for m in InitialMode]
    assert list(choices["baseline"]) == [m.value for m in BaselineMode]


def test_options_of_strings_and_their_refusals():
    o = Options.of("laid", "numerics", "held")
    assert (o.initial_state, o.floor, o.baseline) == (InitialMode.LAID, FloorKind.NUMERICS,
                                                      BaselineMode.HELD)
    assert Options.of(floor="my-floor.json").floor == Path("my-floor.json")
    with pytest.raises(ValueError, match="initial_state 'drawn': expected one of auto, laid, "
                                         "settled"):
        Options.of(initial_state="drawn")
    with pytest.raises(ValueError, match="floor 'flat': expected one of model-form, numerics"):
        Options.of(floor="flat")
