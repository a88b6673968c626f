"""plenodecode.io.atomic: temporary sibling + rename, overwrite refusal, folder replacement, permissions."""

from __future__ import annotations

import os
import stat
import sys

import pytest

from plenodecode.io import atomic
from plenodecode.io.atomic import (atomic_output, atomic_outputs, check_destination, is_temporary,
                                   write_bytes_atomic, write_text_atomic)


def _names(folder):
    return sorted(p.name for p in folder.iterdir())


class Boom(RuntimeError):
    pass


@pytest.fixture
def umask027():
    old = os.umask(0o027)
    try:
        yield
    finally:
        os.umask(old)


def test_file_written_and_renamed(tmp_path):
    dest = tmp_path / "sub" / "a.bin"
    with atomic_output(dest) as tmp:
        assert tmp.parent == dest.parent and tmp.is_file() and tmp.stat().st_size == 0
        assert is_temporary(tmp) and tmp.name.startswith(".a.bin.") and tmp.name.endswith(".tmp")
        assert not dest.exists()
        tmp.write_bytes(b"payload")
    assert dest.read_bytes() == b"payload"
    assert _names(dest.parent) == ["a.bin"]


@pytest.mark.parametrize("folder", [False, True])
def test_failure_leaves_no_output_and_no_temp(tmp_path, folder):
    dest = tmp_path / ("out" if folder else "out.png")
    with pytest.raises(Boom):
        with atomic_output(dest, folder=folder, suffix=None if folder else ".png") as tmp:
            if folder:
                (tmp / "inner").mkdir()
                (tmp / "inner" / "x.txt").write_text("half")
            else:
                tmp.write_bytes(b"half")
            raise Boom
    assert _names(tmp_path) == []


def test_failure_keeps_the_existing_output(tmp_path):
    dest = tmp_path / "a.txt"
    dest.write_text("old")
    with pytest.raises(Boom):
        with atomic_output(dest, overwrite=True) as tmp:
            tmp.write_text("new")
            raise Boom
    assert dest.read_text() == "old" and _names(tmp_path) == ["a.txt"]


def test_suffix_for_format_picking_writers(tmp_path):
    with atomic_output(tmp_path / "img.exr", suffix=".exr") as tmp:
        assert tmp.suffix == ".exr" and is_temporary(tmp)
        tmp.write_bytes(b"x")
    assert (tmp_path / "img.exr").read_bytes() == b"x"
    with pytest.raises(ValueError, match="suffix"):
        with atomic_output(tmp_path / "b", suffix="/x"):
            pass


def test_overwrite_refusal_and_replacement(tmp_path):
    dest = tmp_path / "a.txt"
    dest.write_text("old")
    with pytest.raises(FileExistsError, match=r"a\.txt exists; pass overwrite=True to replace it"):
        with atomic_output(dest):
            raise AssertionError("the block must not run")
    with pytest.raises(FileExistsError):
        write_text_atomic(dest, "new")
    with pytest.raises(FileExistsError):
        check_destination(dest, False)
    assert dest.read_text() == "old" and _names(tmp_path) == ["a.txt"]
    write_text_atomic(dest, "new", overwrite=True)
    assert dest.read_text() == "new" and _names(tmp_path) == ["a.txt"]


def test_refuses_output_that_appears_while_writing(tmp_path):
    dest = tmp_path / "a.txt"
    with pytest.raises(FileExistsError):
        with atomic_output(dest) as tmp:
            tmp.write_text("mine")
            dest.write_text("someone else's")
    assert dest.read_text() == "someone else's" and _names(tmp_path) == ["a.txt"]


def test_check_destination_creates_parent_and_refuses_dangling_symlink(tmp_path):
    p = check_destination(tmp_path / "x" / "y" / "z.txt", False)
    assert p.parent.is_dir() and not p.exists()
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "missing")
    with pytest.raises(FileExistsError):
        check_destination(link, False)


def test_folder_replacement(tmp_path):
    dest = tmp_path / "lf.zarr"
    dest.mkdir()
    (dest / "old.txt").write_text("old")
    with pytest.raises(FileExistsError):
        with atomic_output(dest, folder=True):
            pass
    assert (dest / "old.txt").read_text() == "old"
    with atomic_output(dest, folder=True, overwrite=True) as tmp:
        assert tmp.is_dir() and list(tmp.iterdir()) == [] and is_temporary(tmp)
        (tmp / "new.txt").write_text("new")
        assert (dest / "old.txt").exists()          # the old folder stays until the rename
    assert _names(dest) == ["new.txt"] and (dest / "new.txt").read_text() == "new"
    assert _names(tmp_path) == ["lf.zarr"]          # no temporary, no '.old' folder left


def test_folder_replaces_file_but_a_file_never_replaces_a_folder(tmp_path):
    """A folder output replaces a file with overwrite=True; a file output never replaces a folder (it deleted the
    folder and everything in it: '-o photo.png --overwrite' naming a folder photo.png)."""
    a = tmp_path / "a"
    a.write_text("file")
    with atomic_output(a, folder=True, overwrite=True) as tmp:
        (tmp / "x").write_text("1")
    assert a.is_dir() and (a / "x").read_text() == "1"
    with pytest.raises(IsADirectoryError, match="is a folder; an output file never replaces a folder"):
        write_bytes_atomic(a, b"back to a file", overwrite=True)
    assert a.is_dir() and (a / "x").read_text() == "1"
    assert _names(tmp_path) == ["a"]


def test_failed_folder_rename_puts_the_old_folder_back(tmp_path, monkeypatch):
    dest = tmp_path / "views"
    dest.mkdir()
    (dest / "old.txt").write_text("old")
    real = os.replace
    calls = []

    def flaky(src, dst):
        calls.append((src, dst))
        if len(calls) == 2:                         # 1: old folder aside, 2: new folder in
            raise OSError("disk full")
        return real(src, dst)

    monkeypatch.setattr(atomic.os, "replace", flaky)
    with pytest.raises(OSError, match="disk full"):
        with atomic_output(dest, folder=True, overwrite=True) as tmp:
            (tmp / "new.txt").write_text("new")
    assert len(calls) == 3 and _names(dest) == ["old.txt"] and _names(tmp_path) == ["views"]


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX permissions")
def test_permissions_follow_the_umask(tmp_path, umask027):
    with atomic_output(tmp_path / "f.bin") as tmp:
        tmp.write_bytes(b"1")
    with atomic_output(tmp_path / "d", folder=True) as tmp:
        pass
    write_text_atomic(tmp_path / "t.txt", "x")
    assert stat.S_IMODE((tmp_path / "f.bin").stat().st_mode) == 0o640
    assert stat.S_IMODE((tmp_path / "t.txt").stat().st_mode) == 0o640
    assert stat.S_IMODE((tmp_path / "d").stat().st_mode) == 0o750
    os.umask(0o002)
    write_bytes_atomic(tmp_path / "g.bin", b"1")
    assert stat.S_IMODE((tmp_path / "g.bin").stat().st_mode) == 0o664


def test_write_bytes_chunks_and_text_encoding(tmp_path):
    p = write_bytes_atomic(tmp_path / "c.bin", (bytes([i]) * 3 for i in range(4)))
    assert p.read_bytes() == b"\x00\x00\x00\x01\x01\x01\x02\x02\x02\x03\x03\x03"
    t = write_text_atomic(tmp_path / "t.txt", "a\r\nb\u00e9", encoding="utf-8")
    assert t.read_bytes() == "a\r\nb\u00e9".encode("utf-8")


def test_atomic_outputs_commit_all_or_nothing(tmp_path):
    img, side = tmp_path / "m.png", tmp_path / "m.json"
    with pytest.raises(Boom):
        with atomic_outputs([img, side], keep_suffix=True) as (ti, ts):
            assert ti.suffix == ".png" and ts.suffix == ".json"
            ti.write_bytes(b"png")
            raise Boom
    assert _names(tmp_path) == []
    with atomic_outputs([img, side]) as (ti, ts):
        ti.write_bytes(b"png")
        ts.write_text("{}")
    assert img.read_bytes() == b"png" and side.read_text() == "{}" and _names(tmp_path) == ["m.json", "m.png"]


def test_atomic_outputs_refuses_before_creating_anything(tmp_path):
    a, b = tmp_path / "new" / "a.raw", tmp_path / "b.txt"
    b.write_text("keep")
    with pytest.raises(FileExistsError, match="b.txt exists"):
        with atomic_outputs([a, b]):
            raise AssertionError("the block must not run")
    assert _names(tmp_path) == ["b.txt"]
    with pytest.raises(ValueError, match="paths"):
        with atomic_outputs([b, tmp_path / "." / "b.txt"], overwrite=True):
            pass


def test_atomic_outputs_rolls_back_new_files_when_a_rename_fails(tmp_path, monkeypatch):
    a, b = tmp_path / "a.raw", tmp_path / "a.txt"
    real = atomic.commit

    def flaky(tmp, dest):
        if str(dest).endswith(".txt"):
            raise OSError("no space")
        return real(tmp, dest)

    monkeypatch.setattr(atomic, "commit", flaky)
    with pytest.raises(OSError, match="no space"):
        with atomic_outputs([a, b]) as (ta, tb):
            ta.write_bytes(b"raw")
            tb.write_text("txt")
    assert _names(tmp_path) == []


def test_is_temporary_names():
    assert is_temporary(".summary.json.0123456789ab.tmp")
    assert is_temporary(".view.png.0123456789ab.tmp.png")
    assert is_temporary(".lf.zarr.0123456789ab.old")
    for name in ("summary.json", ".hidden", "x.tmp", ".a.0123456789ab.partial", ".a.0123.tmp"):
        assert not is_temporary(name)


def _dead_pid() -> int:
    """The id of a process that has exited and been reaped."""
    import subprocess
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_new_names_carry_the_owner_and_stay_recognised(tmp_path):
    with atomic_output(tmp_path / "lf.zarr", folder=True) as tmp:
        pid, host, token = tmp.name[len(".lf.zarr."):-len(".tmp")].split("-")
        assert int(pid) == os.getpid() and len(host) == 8 and len(token) == 12 and is_temporary(tmp)
    assert is_temporary(".lf.zarr.4321-0a1b2c3d-0123456789ab.tmp")
    assert is_temporary(".view.png.4321-0a1b2c3d-0123456789ab.tmp.png")
    assert is_temporary(".lf.zarr.4321-0a1b2c3d-0123456789ab.old")


@pytest.mark.skipif(os.name == "nt", reason="pid probing is POSIX-only")
def test_next_write_removes_leftovers_of_dead_runs_only(tmp_path):
    """A killed run's temporary (dead pid on this host) goes at the next write into the folder; a live run's
    stays; one of another host goes only once older than STALE_AFTER_S."""
    import subprocess
    import time

    host = atomic._host_tag()
    dead = tmp_path / f".lf.zarr.{_dead_pid()}-{host}-0123456789ab.tmp"
    (dead / "0.0.0").mkdir(parents=True)
    (dead / "0.0.0" / "chunk").write_bytes(b"x" * 1000)
    dead_file = tmp_path / f".view.png.{_dead_pid()}-{host}-0123456789ab.tmp.png"
    dead_file.write_bytes(b"half")
    live_run = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        live = tmp_path / f".lf.zarr.{live_run.pid}-{host}-abcdefabcdef.tmp"
        live.mkdir()
        other_host_new = tmp_path / ".a.png.4321-ffffffff-0123456789ab.tmp"
        other_host_new.write_bytes(b"")
        other_host_old = tmp_path / ".b.png.4321-ffffffff-0123456789ab.tmp"
        other_host_old.write_bytes(b"")
        no_owner_old = tmp_path / ".c.png.0123456789ab.tmp"
        no_owner_old.write_bytes(b"")
        long_ago = time.time() - atomic.STALE_AFTER_S - 60
        for p in (other_host_old, no_owner_old):
            os.utime(p, (long_ago, long_ago))
        write_text_atomic(tmp_path / "summary.json", "{}")
        assert _names(tmp_path) == sorted([live.name, other_host_new.name, "summary.json"])
        assert live.is_dir()
    finally:
        live_run.kill()
        live_run.wait()
    write_text_atomic(tmp_path / "summary.json", "{}", overwrite=True)      # now its owner is gone too
    assert _names(tmp_path) == sorted([other_host_new.name, "summary.json"])


@pytest.mark.skipif(os.name == "nt", reason="pid probing is POSIX-only")
def test_a_folder_left_aside_by_a_dead_run_is_put_back(tmp_path):
    """A run killed between the two renames of a folder replacement left the old output in '.old': restored."""
    aside = tmp_path / f".out.{_dead_pid()}-{atomic._host_tag()}-0123456789ab.old"
    (aside / "out").mkdir(parents=True)
    (aside / "out" / "a.txt").write_text("old")
    write_text_atomic(tmp_path / "other.txt", "x")
    assert _names(tmp_path) == ["other.txt", "out"] and (tmp_path / "out" / "a.txt").read_text() == "old"
