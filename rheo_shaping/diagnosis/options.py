"""The diagnosis's option switches and their one set of defaults, shared by
:func:`~.engine.diagnose` and ``rheo-shaping diagnose``.

Each switch is a str-valued enum (the command's choices and the JSON carry its value).
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path


class InitialMode(StrEnum):
    """How each record's model starts (:mod:`.initial_state`)."""

    AUTO = "auto"           # laid when the records show the sheet moving before the tool
    LAID = "laid"           # the first frame's sheet released at t = 0
    SETTLED = "settled"     # the scenario's drape settled before t = 0


class FloorKind(StrEnum):
    """What the gap and the adequacy are judged against (:mod:`.floor`); a calibration
    file's path (``*.json``) is the third choice."""

    MODEL_FORM = "model-form"   # the dynamic world's calibration for this configuration
    NUMERICS = "numerics"       # the stored finer-chain null (numerics only)


class BaselineMode(StrEnum):
    """How the sheet knobs are taken (:mod:`.baseline`; the chain is fitted either way)."""

    CALIBRATED = "calibrated"   # fitted within their tolerances
    HELD = "held"               # kept as written (a cell already calibrated)


@dataclass(frozen=True, kw_only=True)
class Options:
    """The switches of one diagnosis."""

    initial_state: InitialMode = InitialMode.AUTO
    floor: FloorKind | Path = FloorKind.MODEL_FORM
    baseline: BaselineMode = BaselineMode.CALIBRATED

    @classmethod
    def of(cls, initial_state: str = "auto", floor: str | Path = "model-form",
           baseline: str = "calibrated") -> Options:
        """The options of plain strings (a ValueError names the choices)."""
        return cls(initial_state=initial_mode_of(initial_state), floor=floor_of(floor),
                   baseline=baseline_mode_of(baseline))


#: The defaults of :func:`~.engine.diagnose` and of ``rheo-shaping diagnose``.
DEFAULTS = Options()


def _choice(enum, value: str, what: str):
    """``enum(value)``, or a ValueError that names ``what`` and the choices."""
    try:
        return enum(value)
    except ValueError:
        raise ValueError(f"{what} {value!r}: expected one of "
                         f"{', '.join(m.value for m in enum)}") from None


def initial_mode_of(value: str) -> InitialMode:
    """The :class:`InitialMode` of ``value`` (a ValueError names the choices)."""
    return _choice(InitialMode, value, "initial_state")


def baseline_mode_of(value: str) -> BaselineMode:
    """The :class:`BaselineMode` of ``value`` (a ValueError names the choices)."""
    return _choice(BaselineMode, value, "baseline")


def floor_of(value: str | Path) -> FloorKind | Path:
    """A :class:`FloorKind`, or the path of a calibration file (``*.json``)."""
    if isinstance(value, Path) or str(value).endswith(".json"):
        return Path(value)
    try:
        return FloorKind(value)
    except ValueError:
        raise ValueError(f"floor {value!r}: expected one of "
                         f"{', '.join(m.value for m in FloorKind)} or a calibration file "
                         "(.json)") from None
