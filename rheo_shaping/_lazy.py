"""A package's public API, imported on first use (PEP 562 module ``__getattr__``).

Each subpackage's ``__init__`` names its public entry points and the module that
defines them; ``import rheo_shaping.sheet`` then costs nothing until a name is used,
so the API of a subpackage never drags in numba, scipy or matplotlib by itself.
"""
from __future__ import annotations

import importlib
from typing import Any, Callable


def lazy_api(package: str, api: dict[str, list[str]]
             ) -> tuple[list[str], Callable[[str], Any], Callable[[], list[str]]]:
    """``(__all__, __getattr__, __dir__)`` of ``package`` whose names are ``api``
    (module of the package -> names it defines)."""
    where = {name: module for module, names in api.items() for name in names}

    def __getattr__(name: str) -> Any:
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{module}"), name)

    def __dir__() -> list[str]:
        return sorted(where)

    return sorted(where), __getattr__, __dir__
