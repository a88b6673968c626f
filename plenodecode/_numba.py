"""Where numba keeps the compiled kernels, and a one-line notice when a command compiles some.

numba's on-disk cache (``cache=True``) lands by default in a ``__pycache__`` folder beside each module,
that is inside the installed package.  :func:`use_user_cache` points it at a user cache directory instead
(``$NUMBA_CACHE_DIR`` when set, else ``$XDG_CACHE_HOME/plenodecode/numba``, ``~/.cache/plenodecode/numba``
without XDG); ``plenodecode/__init__.py`` calls it, so it runs before any kernel module imports numba.

Every kernel module decorates its kernels with :func:`njit` (``numba.njit`` with ``cache=True``).  The first
time a process compiles a kernel that is not in the cache (numba's ``numba:compile`` event, raised only on a
cache miss), the callback set by :func:`set_compile_notice` (the CLI: one line on stderr) or, without one,
the log receives ``"compiling decode kernels (first run only, ~4 s)..."``, once per group of kernels and cache
directory: a group's kernels are compiled by several commands (a white image's fit, its report at full resolution,
``calibrate --scene``), and the notice of the first says it for all, so that 'first run only' holds; a marker file
per group, plenodecode and numba version in the cache directory (:func:`notice_marker`) records it.  Batch workers relay
the group to the process that started them (:func:`relay_compile_notices`), which says it once.

Importing this module is light: numba is imported by :func:`njit`, that is by the kernel modules.
"""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path
from typing import Any, Callable


log = logging.getLogger(__name__)

#: module prefix -> group of kernels named in the compile notice and by ``plenodecode warmup``
KERNEL_GROUPS: dict[str, str] = {
    "plenodecode.synthetic": "synthetic",
    "plenodecode.calib": "calibration",
    "plenodecode.decoding.focused": "total-focus",
    "plenodecode.decoding": "decode",
    "plenodecode.render": "refocus",
    "plenodecode.depth": "depth",
}

#: group -> CPU seconds its kernels take to compile (2-core AMD EPYC, numba 0.68; ``plenodecode warmup`` with the
#: numba:compile events timed), or (low, high) where the first command of the group compiles different kernels.
#: 'decode': demosaic 1.6 s, the slicing kernels 1.3 s, hex -> rect 0.8 s (a cold ``plenodecode decode``: 3.7-4.0 s);
#: 'calibration': the notice of the first calibrating command stands for the group, and what that command compiles
#: measured (compile events timed, fresh cache) 0.9-1.0 s for a white image (the bundled illum-mini white, the real
#: ant-leg radiometry frame), 1.9 s for ``calibrate --scene`` on the real F01 JPEG (the rim fit, and the hot-pixel
#: kernel of images from 4 Mpx on, 0.8 s, which a full-size white compiles too); 'refocus': a focal stack's tiled
#: shift-sum and the Fourier slice (a single shift-sum photograph goes through OpenCV and compiles nothing).
COMPILE_SECONDS: dict[str, float | tuple[float, float]] = {
    "synthetic": 6.0,
    "calibration": (1.0, 2.0),
    "total-focus": 4.0,
    "decode": 4.0,
    "refocus": 9.0,
    "depth": 4.0,
}

_state: dict[str, Any] = {"notify": None, "relay": None, "announced": set(), "listening": False}


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/plenodecode/numba`` (``~/.cache/plenodecode/numba`` when XDG_CACHE_HOME is unset)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "plenodecode" / "numba"


def use_user_cache() -> str:
    """Make numba cache compiled kernels in the user cache directory; return that directory.

    ``$NUMBA_CACHE_DIR`` wins when set; otherwise it is set to :func:`default_cache_dir` (so worker
    processes inherit it).  When numba was imported before plenodecode its configuration is updated too;
    kernels decorated after this call use the directory.
    """
    path = os.environ.get("NUMBA_CACHE_DIR") or str(default_cache_dir())
    os.environ["NUMBA_CACHE_DIR"] = path
    numba = sys.modules.get("numba")
    if numba is not None and getattr(numba, "config", None) is not None and not numba.config.CACHE_DIR:
        numba.config.CACHE_DIR = path
    return path


def group_of(module: str) -> str | None:
    """The kernel group of a module name (longest matching prefix of :data:`KERNEL_GROUPS`), or None."""
    best = None
    for prefix, group in KERNEL_GROUPS.items():
        if (module == prefix or module.startswith(prefix + ".")) and (best is None or len(prefix) > len(best[0])):
            best = (prefix, group)
    return best[1] if best else None


def compile_message(group: str) -> str:
    """``'compiling decode kernels (first run only, ~4 s)...'``, ``'... (first run only, ~1-2 s)...'``
    (:data:`COMPILE_SECONDS`)."""
    seconds = COMPILE_SECONDS.get(group)
    if isinstance(seconds, tuple):
        estimate = f", ~{seconds[0]:.0f}-{seconds[1]:.0f} s"
    else:
        estimate = f", ~{seconds:.0f} s" if seconds else ""
    return f"compiling {group} kernels (first run only{estimate})..."


def notice_marker(group: str) -> Path:
    """The file whose presence in the kernel cache directory says that ``group``'s compile notice was given for this
    plenodecode and numba: ``<cache>/compile-notices/<group>-<plenodecode version>-numba<numba version>`` (a new
    numba recompiles every kernel, so it gets the notice again)."""
    from importlib import metadata

    try:
        version = metadata.version("plenodecode")
    except metadata.PackageNotFoundError:     # run from a source tree that was never installed
        version = "source"
    numba_version = getattr(sys.modules.get("numba"), "__version__", None) or metadata.version("numba")
    cache = Path(os.environ.get("NUMBA_CACHE_DIR") or default_cache_dir())
    return cache / "compile-notices" / f"{group}-{version}-numba{numba_version}"


def _first_notice(group: str) -> bool:
    """Whether ``group``'s notice was never given with this cache directory; marks it given (best effort: an
    unwritable cache directory gives the notice every time, as numba then compiles every time)."""
    marker = notice_marker(group)
    if marker.is_file():
        return False
    try:
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.touch()
    except OSError:
        pass
    return True


def set_compile_notice(notify: Callable[[str], None] | None) -> None:
    """Send the compile notice to ``notify(message)`` (None: to the log, at INFO)."""
    _state["notify"] = notify


def relay_compile_notices(send: Callable[[str], None] | None) -> None:
    """In a worker process: hand each kernel group it starts compiling to ``send(group)`` instead of announcing
    it, so that the process that started the workers announces it once (:func:`announce`) for all of them."""
    _state["relay"] = send


def announce(group: str) -> None:
    """Say that ``group``'s kernels are compiling, once per process and cache directory (:func:`notice_marker`):
    :func:`set_compile_notice`'s callback, or the log; in a worker with :func:`relay_compile_notices`, the relay."""
    if group in _state["announced"]:
        return
    _state["announced"].add(group)
    relay = _state["relay"]
    if relay is not None:
        relay(group)
        return
    if not _first_notice(group):
        return
    message = compile_message(group)
    notify = _state["notify"]
    if notify is not None:
        notify(message)
    else:
        log.info(message)


def _listen() -> None:
    """Register (once) a listener of numba's ``numba:compile`` event, which numba raises on a cache miss."""
    if _state["listening"]:
        return
    from numba.core import event

    class _CompileNotice(event.Listener):
        def on_start(self, ev: Any) -> None:
            dispatcher = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
            func = getattr(dispatcher, "py_func", None)
            module = getattr(func, "__module__", "") or ""
            if module.startswith("plenodecode"):
                announce(group_of(module) or "plenodecode")

        def on_end(self, ev: Any) -> None:
            pass

    event.register("numba:compile", _CompileNotice())
    _state["listening"] = True


def njit(*args: Any, **options: Any) -> Any:
    """``numba.njit`` with ``cache=True`` (in :func:`use_user_cache`'s directory) and the compile notice.

    Used as ``@njit`` or ``@njit(parallel=True, ...)``, like numba's.
    """
    use_user_cache()
    _listen()
    import numba

    options.setdefault("cache", True)
    return numba.njit(*args, **options)


def run_in_blocks(call: Callable[[int, int], Any], n: int, *, blocks_per_thread: int = 8) -> list[Any]:
    """Call ``call(i0, i1)`` on blocks covering ``0 .. n`` from a pool of ``numba.get_num_threads()`` threads.

    The parallel loop of a serial ``nogil`` kernel: such a kernel compiles in about half the time of the same
    loop under ``parallel=True`` (no parfor lowering), and small blocks handed out as threads free up keep both
    cores busy when the machine is shared.  Returns the calls' results in block order.
    """
    import numba

    threads = max(1, numba.get_num_threads())
    n_blocks = max(1, min(n, threads * blocks_per_thread))
    cuts = [round(i * n / n_blocks) for i in range(n_blocks + 1)]
    spans = [(a, b) for a, b in zip(cuts[:-1], cuts[1:]) if b > a]
    if threads == 1 or len(spans) < 2:
        return [call(a, b) for a, b in spans]
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(threads) as pool:
        return list(pool.map(lambda span: call(*span), spans))


__all__ = ["KERNEL_GROUPS", "COMPILE_SECONDS", "default_cache_dir", "use_user_cache", "group_of",
           "compile_message", "notice_marker", "set_compile_notice", "relay_compile_notices", "announce", "njit",
           "run_in_blocks"]
