"""numba kernels of the control layer, cached across processes in a directory keyed by this package's sources.

numba keys a cached kernel by the source of its own file only, but these kernels call each other across modules
(the control law compiles the treecode and the navigation function into itself): after an edit of the callee
alone, numba would load the caller compiled with the old callee.  The cache here lives in a directory named by a
hash of all of this package's sources, so an edited module never meets a stale compiled caller.  It is under
``NUMBA_CACHE_DIR`` when that is set, else in this package's ``__pycache__``, else in the user's cache directory;
when a new one is made, those of other sources untouched for a day are removed (a process running other sources
may still be writing to a newer one).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import time
from pathlib import Path

from numba import config, njit

_HERE = Path(__file__).resolve().parent
_PREFIX = "mrodrake-kernels-"
_STALE_SECONDS = 86400.0


def sources_key(package: Path = _HERE) -> str:
    """Hash of the names and contents of the ``*.py`` files of ``package``."""
    digest = hashlib.sha256()
    for path in sorted(package.glob("*.py")):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def _writable(base: Path) -> bool:
    try:
        base.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return os.access(base, os.W_OK | os.X_OK)


def _cache_dir() -> str | None:
    user = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "mrodrake"
    bases = [Path(config.CACHE_DIR)] if config.CACHE_DIR else [_HERE / "__pycache__", user]
    base = next((b for b in bases if _writable(b)), None)
    if base is None:
        return None
    path = base / (_PREFIX + sources_key())
    if not path.exists():
        for old in base.glob(_PREFIX + "*"):
            try:
                stale = time.time() - old.stat().st_mtime > _STALE_SECONDS
            except OSError:
                continue
            if stale:
                shutil.rmtree(old, ignore_errors=True)
    return str(path)


#: Where the kernels of this package are cached (None: nowhere writable, so numba's own choice).
CACHE_DIR = _cache_dir()


def cached_njit(**options):
    """``numba.njit(cache=True, **options)`` with the cache in :data:`CACHE_DIR`."""

    def decorate(fn):
        saved = config.CACHE_DIR
        if CACHE_DIR is not None:
            config.CACHE_DIR = CACHE_DIR
        try:
            return njit(cache=True, **options)(fn)
        finally:
            config.CACHE_DIR = saved

    return decorate
