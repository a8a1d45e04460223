"""The diagnosis's one compiled (numba) kernel: measured profile points projected on the
model's centrelines (:func:`project`), the per-run cost every simulation of a diagnosis
pays after the sheet step.  Cached on disk by content like the sheet's kernel
(:mod:`rheo_shaping._numba_cache`)."""
from __future__ import annotations

from pathlib import Path

from ..._numba_cache import register

register(Path(__file__).resolve().parent, "rheo_shaping_diagnosis")

from .project import project  # noqa: E402,F401

__all__ = ["project"]
