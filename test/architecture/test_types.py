"""The type check of the core and the validation package: mypy with setup.cfg's [mypy]
settings (the ROS side, nodes/ and cli/: test/package/test_types_ros.py).

Runs in the core stage and the noble stage, so the annotations hold against numpy 2's
stubs (and numba's, which 0.68 ships) and against numpy 1.26's (noble's numba 0.59 ships
none: its names are Any there).  mypy's cache: test/_support/typecheck.py.
"""
from __future__ import annotations

from _support.typecheck import require_mypy_clean

#: What is checked, under rheo_shaping/: the core but nodes/ and cli/ (the ROS side).
CHECKED = ("params", "material", "identification", "sheet", "planning", "safety", "records",
           "study", "diagnosis", "gapwatch", "adaptive", "parallel.py", "units.py",
           "jsonable.py", "_lazy.py")
#: Checked whole beside it: the validation package (its worlds, benchmark, campaigns).
VALIDATION = "rheo_shaping_validation"


def test_core_subpackages_type_check():
    """mypy finds no error in the checked part of the core and in the validation package."""
    require_mypy_clean(CHECKED, extra=(VALIDATION,))
