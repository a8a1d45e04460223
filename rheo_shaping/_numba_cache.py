"""One on-disk cache for the package's compiled (numba) kernels, found by content.

A kernel package (``sheet/kernel``, ``worlds/kernel``) calls :func:`register` with its
directory before it compiles anything.  Its functions are then cached (``cache=True``) in
a user cache directory, so a read-only install (colcon prefix, site-packages) compiles
once per user: ``$NUMBA_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/rheo_shaping/numba``
(``~/.cache/rheo_shaping/numba``), in a folder named by the content of the kernel's
modules and the numba version (:func:`cache_folder`), not by their path.  So every
install of the same source on the same numba shares it, a change in any module of a
kernel (numba inlines the calls between them, and its own cache only sees the file of
each function) compiles the whole kernel anew, and venvs with different numbas keep apart.
"""
from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Literal, TypedDict


class JitOptions(TypedDict):
    """The numba options of every compiled function of the package (``@njit(**JIT)``)."""

    cache: bool
    nogil: bool
    fastmath: bool
    error_model: Literal["python", "numpy"]


#: Cached on disk (by content, below), the GIL released, no fast-math (the closed-form tests
#: ask for the exact arithmetic), numpy's error model (a 0/0 is a NaN the caller sees).
NUMBA_OPTIONS: JitOptions = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")


def user_cache_dir() -> str:
    """Directory [path] where compiled kernels are cached for this user."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return str(Path(base) / "rheo_shaping" / "numba")


if not os.environ.get("NUMBA_CACHE_DIR"):
    os.environ["NUMBA_CACHE_DIR"] = user_cache_dir()
    if "numba" in sys.modules:                     # numba read its config already
        sys.modules["numba"].config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]

from numba.core import caching as _caching  # noqa: E402

# the user-directory locator: UserProvidedCacheLocator in the numba of requirements-core
# (0.68 here); numba 0.59, Ubuntu 24.04's python3-numba (what rosdep installs for Jazzy),
# has it only as _UserProvidedCacheLocator.  The type check reads numba 0.68's types.
if TYPE_CHECKING:
    from numba.core.caching import UserProvidedCacheLocator as _UserDirLocator
else:
    _UserDirLocator = getattr(_caching, "UserProvidedCacheLocator", None) \
        or _caching._UserProvidedCacheLocator

#: Registered kernel directories -> the prefix of their cache folders.
_KERNELS: dict[Path, str] = {}


def source_digest(directory: Path) -> str:
    """SHA-256 (20 hex digits) of a kernel's modules in ``directory``: names and contents."""
    h = hashlib.sha256()
    for path in sorted(Path(directory).glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:20]


def cache_folder(directory: Path) -> str:
    """Name of a registered kernel's cache folder in ``$NUMBA_CACHE_DIR``: its prefix, its
    source's content and the numba version (numba's index holds the entries of one numba
    version and a mismatch empties it, so two venvs with two numbas in one folder would
    each compile anew every run, overwriting the other's)."""
    import numba
    d = Path(directory).resolve()
    return f"{_KERNELS[d]}_{source_digest(d)}_numba{numba.__version__}"


class _ContentCacheLocator(_UserDirLocator):
    """numba's user-directory cache, with the folder named by the kernel's source content
    and the numba version (:func:`cache_folder`) instead of its directory: a new install
    of the same source finds the code compiled by an earlier one (numba checks its own
    version and the CPU in the index)."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        # numba's config sets its options at run time (from the environment): getattr, as
        # its types do not list them
        self._cache_path = os.path.join(getattr(_caching.config, "CACHE_DIR"),
                                        cache_folder(Path(py_file).resolve().parent))

    @classmethod
    def from_function(cls, py_func, py_file):
        if Path(py_file).resolve().parent not in _KERNELS:
            return None                           # only the registered kernels' functions
        return super().from_function(py_func, py_file)


def register(directory: Path, prefix: str) -> None:
    """Cache the compiled functions of the modules in ``directory`` by content, in folders
    named ``prefix``_<digest>_numba<version>."""
    _KERNELS[Path(directory).resolve()] = prefix
    if _ContentCacheLocator not in _caching.CacheImpl._locator_classes:
        _caching.CacheImpl._locator_classes.insert(0, _ContentCacheLocator)
