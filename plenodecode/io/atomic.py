"""Atomic outputs: every file or folder plenodecode writes goes to a temporary sibling and is renamed.

House rule 5 (docs/design.md): a failed run leaves no half-written output and nothing is
replaced without ``overwrite=True``.  This module is the one implementation of it.

Names
-----
Temporary outputs are hidden siblings of the destination, ``.<name>.<owner>-<12 hex>.tmp`` (plus
``suffix`` when a writer picks its format from the extension, e.g. ``.<name>.<owner>-<hex>.tmp.png``
for OpenImageIO), where ``<owner>`` is ``<pid>-<host>``: the writing process's id and 8 hex digits
of a hash of its host name.  A folder that is replaced is first moved into
``.<name>.<owner>-<12 hex>.old`` and deleted after the rename.  :func:`is_temporary` recognises
both (and the names without an owner that earlier versions wrote).

Leftovers of killed runs
------------------------
A killed run cannot clean up, so the next one does: creating a temporary in a folder first removes
the stale leftovers there (:func:`remove_stale_temporaries`): those whose owner is a process of this
host that no longer runs, and those of other hosts (or without an owner) not modified for
:data:`STALE_AFTER_S`.  A temporary of a live run, here or on another machine sharing the folder,
is left alone.  A ``.old`` folder whose destination is missing (the run died between its two
renames) is moved back into place instead of deleted.

Permissions
-----------
Files are created with mode ``0o666`` and folders with ``0o777``, minus the process umask, like
any file a program opens (``tempfile.mkstemp``/``mkdtemp`` would give 0600 / 0700).

Atomicity
---------
A single output is committed by one :func:`os.replace` (same folder, so same file system).  A
folder that replaces an existing folder takes two renames (old one aside, new one in); if the
second fails the old folder is put back.  :func:`atomic_outputs` commits several outputs one after
another once all are written: an error while writing leaves none of them; an error during the
renames removes the outputs it had already created (ones that replaced an older file cannot be
restored).  Data are not ``fsync``-ed: the guarantee covers crashes of the process, not of the
machine.
"""

from __future__ import annotations

import contextlib
import logging
import os
import hashlib
import re
import shutil
import signal
import socket
import threading
import time
import uuid
from pathlib import Path
from typing import Callable, Iterable, Iterator, Sequence

log = logging.getLogger(__name__)

#: Marker in the names of temporary outputs, and of replaced folders waiting for deletion.
TEMP_MARK = ".tmp"
OLD_MARK = ".old"
_TOKEN_HEX = 12
#: Longest part of the destination's name kept in a temporary name (NAME_MAX is 255 bytes).
_NAME_KEEP = 160
#: A leftover of another host, or one without an owner, is stale when not modified for this long (seconds).
STALE_AFTER_S = 24 * 3600.0
_LEFTOVER = re.compile(r"^\.(?P<name>.+)\.(?:(?P<pid>[0-9]+)-(?P<host>[0-9a-f]{8})-)?[0-9a-f]{%d}"
                       r"(?P<kind>\.tmp(?:\.[^.]*)?|\.old)$" % _TOKEN_HEX)


def check_destination(path: str | os.PathLike, overwrite: bool) -> Path:
    """Refuse an existing output unless ``overwrite``; create the parent folder.

    Parameters
    ----------
    path : path-like
        The output file or folder.
    overwrite : bool
        Allow replacing an existing ``path``.

    Returns
    -------
    Path

    Raises
    ------
    FileExistsError
        ``path`` exists (or is a dangling symlink) and ``overwrite`` is False.
    OSError
        ``path`` cannot be created (:func:`refuse_unwritable`).
    """
    p = Path(path)
    _refuse_existing(p, overwrite)
    refuse_unwritable(p)
    p.parent.mkdir(parents=True, exist_ok=True)
    return p


def refuse_unwritable(path: str | os.PathLike) -> None:
    """Raise when the output ``path`` cannot be created: :class:`NotADirectoryError` when the nearest existing
    path above it is a file, :class:`PermissionError` when that folder is not writable (permissions, a read-only
    disk).  For checks before any work; creates nothing."""
    folder = Path(os.path.abspath(path)).parent
    while not os.path.lexists(folder):
        folder = folder.parent
    if not folder.is_dir():
        raise NotADirectoryError(f"cannot write {path}: {folder} is a file, not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise PermissionError(f"cannot write {path}: no permission to write in {folder} (or a read-only disk)")


def _refuse_existing(p: Path, overwrite: bool) -> None:
    if not overwrite and os.path.lexists(p):
        raise FileExistsError(f"{p} exists; pass overwrite=True to replace it")


def refuse_folder(path: str | os.PathLike) -> None:
    """Raise :class:`IsADirectoryError` when the output file ``path`` is an existing folder: ``overwrite`` replaces
    a file, never a folder and what it holds (``-o photos.png`` naming a folder of that name)."""
    p = Path(path)
    if p.is_dir() and not p.is_symlink():
        raise IsADirectoryError(f"{p} is a folder; an output file never replaces a folder (name a file, e.g. "
                                f"{p / 'out'}{p.suffix or '.png'})")


def refuse_existing(paths: Iterable[str | os.PathLike], overwrite: bool) -> None:
    """Raise :class:`FileExistsError` for the first of ``paths`` that exists, unless ``overwrite``.

    For writers that check all their outputs before doing any work; creates nothing.
    """
    for p in paths:
        _refuse_existing(Path(p), overwrite)


def is_temporary(path: str | os.PathLike) -> bool:
    """True for the name of a temporary output or a replaced folder that this module creates."""
    return bool(_LEFTOVER.match(Path(path).name))


def destination_of(path: str | os.PathLike) -> Path:
    """The output a temporary name of this module stands for (``dir/.x.png.<token>.tmp.png`` -> ``dir/x.png``);
    any other path unchanged."""
    p = Path(path)
    m = _LEFTOVER.match(p.name)
    return p.with_name(m.group("name")) if m else p


def os_error_text(exc: OSError) -> str:
    """One line for an OSError, naming the output a temporary file stood for (not its temporary name):
    ``'No such file or directory: /x/y.png'``, ``'cannot write /x/y.png: No space left on device'``, or the
    message a raise gave it (``FileExistsError('... pass --overwrite')``), without ``[Errno n]`` or the class."""
    if exc.filename is None or not exc.strerror:     # OSError(28, 'No space left on device'): no '[Errno 28]'
        text = exc.strerror or str(exc)
        return text.splitlines()[0] if text else type(exc).__name__
    dest = destination_of(exc.filename)
    if str(dest) != str(exc.filename):
        return f"cannot write {dest}: {exc.strerror}"
    return f"{exc.strerror}: {exc.filename}"


def temporary_sibling(path: str | os.PathLike, *, folder: bool = False, suffix: str | None = None) -> Path:
    """Create (and return) a new, empty, uniquely named file or folder beside ``path``.

    Parameters
    ----------
    path : path-like
        The destination; its parent folder must exist.
    folder : bool
        Create a folder instead of a file.
    suffix : str, optional
        Appended to the name, e.g. ``'.png'`` for writers that choose the format by extension.

    Returns
    -------
    Path
        ``<parent>/.<name>.<12 hex>.tmp<suffix>``, mode ``0o666`` (file) or ``0o777`` (folder)
        minus the umask.
    """
    return _reserve(Path(path), TEMP_MARK + (suffix or ""), folder)


def _host_tag() -> str:
    """8 hex digits naming this machine in temporary names (SHA-256 of the host name)."""
    return hashlib.sha256(socket.gethostname().encode("utf-8", "replace")).hexdigest()[:8]


def _reserve(p: Path, tail: str, folder: bool) -> Path:
    if "/" in tail or os.sep in tail:
        raise ValueError(f"suffix must be a file extension such as '.png', got {tail[len(TEMP_MARK):]!r}")
    if tail.startswith(TEMP_MARK):  # a new write into this folder: first clear what killed runs left there
        remove_stale_temporaries(p.parent)
    owner = f"{os.getpid()}-{_host_tag()}"
    while True:
        tmp = p.with_name(f".{p.name[:_NAME_KEEP]}.{owner}-{uuid.uuid4().hex[:_TOKEN_HEX]}{tail}")
        try:
            if folder:
                os.mkdir(tmp, 0o777)
            else:
                os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666))
            return tmp
        except FileExistsError:  # pragma: no cover - 48 random bits
            continue


def _pid_alive(pid: int) -> bool:
    """True unless ``pid`` is certainly not a running process of this machine (signal 0 probes it)."""
    if pid == os.getpid():
        return True
    if os.name == "nt":  # os.kill would terminate the process there: never treat a pid as dead
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # PermissionError: it runs, as another user
        return True
    return True


def remove_stale_temporaries(folder: str | os.PathLike, *, max_age_s: float = STALE_AFTER_S) -> list[Path]:
    """Remove the temporaries and replaced folders that killed runs left in ``folder``.

    A leftover (a name :func:`is_temporary` recognises) is stale when its owner is a process of this
    host that is no longer running, or, for leftovers of other hosts and ones without an owner,
    when it was not modified for ``max_age_s`` seconds.  A stale ``.old`` folder whose destination
    is missing is moved back into place (the run died between its two renames).  Errors are logged,
    never raised: cleaning up must not stop a write.

    Parameters
    ----------
    folder : path-like
        The folder to clean (not recursive); a missing folder is fine.
    max_age_s : float
        Age limit for leftovers whose owner cannot be checked.

    Returns
    -------
    list of Path
        The leftovers removed (or moved back).
    """
    here, now, removed = _host_tag(), time.time(), []
    try:
        with os.scandir(folder) as entries:
            candidates = [(e.path, m) for e in entries if (m := _LEFTOVER.match(e.name))]
    except OSError:
        return removed
    for path, m in candidates:
        try:
            if m["pid"] is not None and m["host"] == here:
                stale = not _pid_alive(int(m["pid"]))
            else:
                stale = now - os.lstat(path).st_mtime > max_age_s
            if not stale:
                continue
            dest = Path(folder) / m["name"]
            inside = Path(path) / m["name"]
            whole_name = len(m["name"]) < _NAME_KEEP  # else the name was cut and the destination is unknown
            if m["kind"] == OLD_MARK and whole_name and os.path.lexists(inside) and not os.path.lexists(dest):
                os.replace(inside, dest)
                log.warning("restored %s, which an interrupted run had moved aside", dest)
            discard(path)
            removed.append(Path(path))
            log.info("removed %s, left behind by an interrupted run", path)
        except OSError as exc:  # pragma: no cover - e.g. a read-only folder; the write itself goes on
            log.debug("could not remove the leftover %s: %s", path, exc)
    return removed


def discard(path: str | os.PathLike) -> None:
    """Remove a temporary file or folder if it is there (never follows a symlink)."""
    p = Path(path)
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p, ignore_errors=True)
    else:
        try:
            p.unlink()
        except FileNotFoundError:
            pass


def commit(tmp: str | os.PathLike, dest: str | os.PathLike) -> None:
    """Rename a finished temporary output to ``dest``, replacing whatever is there.

    A file replaces a file (or a symlink) in one :func:`os.replace`.  When ``dest`` is a real
    folder, or ``tmp`` is a folder and ``dest`` exists, the old ``dest`` is moved into a hidden
    ``.old`` folder first and deleted after the rename; if the rename fails it is put back.
    """
    t, d = Path(tmp), Path(dest)
    if os.path.lexists(d) and (t.is_dir() or (d.is_dir() and not d.is_symlink())):
        aside = _reserve(d, OLD_MARK, folder=True)
        os.replace(d, aside / d.name)
        try:
            os.replace(t, d)
        except BaseException:
            os.replace(aside / d.name, d)
            raise
        finally:
            shutil.rmtree(aside, ignore_errors=True)
    else:
        os.replace(t, d)
    log.debug("committed %s", d)


@contextlib.contextmanager
def interrupts_between_steps() -> Iterator[Callable[[], None]]:
    """Context manager for a writer whose steps run on another thread (zarr's I/O loop): Ctrl-C (SIGINT) is held
    back until the yielded ``check()``, called between steps, raises it as KeyboardInterrupt (or until the block
    ends).  An interrupt in the middle of a step would leave that thread writing into the temporary output after
    :func:`atomic_output` removed it, and print its tasks' tracebacks at exit.  Outside the main thread, or under a
    SIGINT handler of the caller's own, nothing changes."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield lambda: None
        return
    caught: list[int] = []

    def check() -> None:
        if caught:
            raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield check
    finally:
        signal.signal(signal.SIGINT, previous)
    check()


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike, *, overwrite: bool = False, folder: bool = False,
                  suffix: str | None = None) -> Iterator[Path]:
    """Context manager: write to the yielded temporary path; it becomes ``path`` on normal exit.

    Parameters
    ----------
    path : path-like
        The output file or folder (its parent folder is created).
    overwrite : bool
        Replace an existing ``path`` (a folder is replaced whole).  Checked on entry and again
        before the rename.
    folder : bool
        Yield an empty temporary folder instead of an empty file.
    suffix : str, optional
        Extension the temporary name ends with (``'.png'``, ``'.exr'``: writers such as
        OpenImageIO pick the format from it).  Default: ``.tmp``.

    Yields
    ------
    Path
        The temporary sibling (already created, empty).  On an exception inside the block, or
        if the rename fails, it is removed and the exception propagates; ``path`` is untouched.

    Raises
    ------
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    IsADirectoryError
        ``path`` is an existing folder and ``folder`` is False (:func:`refuse_folder`), even with ``overwrite``.

    Examples
    --------
    >>> with atomic_output(out / "view.png", suffix=".png") as tmp:   # doctest: +SKIP
    ...     write_png(tmp, image)
    """
    if not folder:
        refuse_folder(path)
    p = check_destination(path, overwrite)
    tmp = temporary_sibling(p, folder=folder, suffix=suffix)
    try:
        yield tmp
        _refuse_existing(p, overwrite)
        commit(tmp, p)
    except BaseException:
        discard(tmp)
        raise


@contextlib.contextmanager
def atomic_outputs(paths: Sequence[str | os.PathLike], *, overwrite: bool = False,
                   keep_suffix: bool = False) -> Iterator[list[Path]]:
    """Context manager for outputs that belong together (an image and its sidecar, ...).

    Every destination is checked before anything is created; the temporaries are renamed in the
    order given, only after the block finished without an exception.

    Parameters
    ----------
    paths : sequence of path-like
        Output files, all different.
    overwrite : bool
        Replace existing files.
    keep_suffix : bool
        Each temporary name ends with its destination's extension (for writers that pick the
        format from it).

    Yields
    ------
    list of Path
        One empty temporary file per destination, in the same order.

    Raises
    ------
    FileExistsError
        One of ``paths`` exists and ``overwrite`` is False (nothing is created).
    """
    ps = [Path(p) for p in paths]
    if len({os.path.abspath(p) for p in ps}) != len(ps):
        raise ValueError(f"paths must all be different, got {[str(p) for p in ps]}")
    for p in ps:
        refuse_folder(p)
    refuse_existing(ps, overwrite)
    for p in ps:
        check_destination(p, True)
    tmps: list[Path] = []
    created: list[Path] = []
    try:
        for p in ps:
            tmps.append(temporary_sibling(p, suffix=p.suffix if keep_suffix else None))
        yield list(tmps)
        refuse_existing(ps, overwrite)
        for t, p in zip(tmps, ps):
            existed = os.path.lexists(p)
            commit(t, p)
            if not existed:
                created.append(p)
    except BaseException:
        for t in tmps:
            discard(t)
        for p in created:  # a rename failed half-way: do not leave an incomplete set behind
            discard(p)
        raise


def write_bytes_atomic(path: str | os.PathLike, data: bytes | bytearray | memoryview | Iterable[bytes | memoryview],
                       *, overwrite: bool = False) -> Path:
    """Write ``data`` (a bytes-like object, or an iterable of them written in order) atomically.

    Returns
    -------
    Path

    Raises
    ------
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    """
    with atomic_output(path, overwrite=overwrite) as tmp:
        with open(tmp, "wb") as fh:
            if isinstance(data, (bytes, bytearray, memoryview)):
                fh.write(data)
            else:
                for chunk in data:
                    fh.write(chunk)
    return Path(path)


def write_text_atomic(path: str | os.PathLike, text: str, *, overwrite: bool = False,
                      encoding: str = "utf-8") -> Path:
    """Write ``text`` atomically (``encoding`` default UTF-8, newlines unchanged).

    Raises
    ------
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    """
    with atomic_output(path, overwrite=overwrite) as tmp:
        with open(tmp, "w", encoding=encoding, newline="") as fh:
            fh.write(text)
    return Path(path)


__all__ = ["check_destination", "refuse_existing", "refuse_folder", "atomic_output", "atomic_outputs",
           "write_bytes_atomic", "write_text_atomic",
           "temporary_sibling", "commit", "discard", "is_temporary", "destination_of", "os_error_text",
           "remove_stale_temporaries", "TEMP_MARK",
           "OLD_MARK", "STALE_AFTER_S"]
