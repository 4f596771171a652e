"""Outputs never destroy what the user owns (issue 14): no input, device, FIFO or folder is
written over, every write is atomic, errors name the user's path, a closed pipe ends quietly."""

import errno
import importlib.resources
import json
import os
import stat
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fdml import outputs
from fdml.cli import main
from fdml.errors import OutputError

#: A cheap fit: steady model, 10 frequencies, a 4 s record (about 0.1 s a run).
FIT = ["--aircraft", "navion", "--model", "steady", "--band", "0.5:5:0.5"]


@pytest.fixture(scope="module")
def record_bytes(tmp_path_factory) -> bytes:
    """A short noisy Navion record made by ``fdml simulate`` (the CLI under test writes it)."""
    path = tmp_path_factory.mktemp("rec") / "rec.csv"
    assert (
        main(
            [
                "simulate",
                "--aircraft",
                "navion",
                "--model",
                "steady",
                "--duration",
                "4",
                "--noise",
                "0.02",
                "--seed",
                "3",
                "-o",
                str(path),
            ]
        )
        == 0
    )  # a draw whose 4 s fit converges
    return path.read_bytes()


@pytest.fixture(scope="module")
def aircraft_bytes() -> bytes:
    return (importlib.resources.files("fdml") / "presets" / "navion.json").read_bytes()


def _fingerprint(path: Path) -> tuple[bytes, int, int]:
    """Bytes, inode and file type of the file at ``path`` (links followed)."""
    st_ = os.stat(path)
    return path.read_bytes(), st_.st_ino, stat.S_IFMT(st_.st_mode)


def _temporaries(folder: Path) -> list[Path]:
    return sorted(folder.rglob(".*.tmp"))


# --- the table: each case makes the -o path next to the input ---------------------------------------
def _same(d, inp):
    return inp


def _symlink(d, inp):
    os.symlink(inp.name, d / "link.out")
    return d / "link.out"


def _hardlink(d, inp):
    os.link(inp, d / "hard.out")
    return d / "hard.out"


def _fifo(d, inp):
    os.mkfifo(d / "pipe.out")
    return d / "pipe.out"


def _chardev(d, inp):
    # a character device node made inside tmp_path (the numbers of the null device: harmless);
    # never a real device of the machine
    if os.geteuid() != 0:
        pytest.skip("making a device node needs root")
    try:
        os.mknod(d / "dev.out", stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except PermissionError:
        pytest.skip("no CAP_MKNOD here")
    return d / "dev.out"


def _folder(d, inp):
    (d / "folder.out").mkdir()
    return d / "folder.out"


def _read_only_folder(d, inp):
    ro = d / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    if os.access(ro, os.W_OK):
        ro.chmod(0o755)
        pytest.skip("this user (root) can write into a read-only folder")
    return ro / "out.file"


CASES = {
    "same file": (_same, "input"),
    "symlink to the input": (_symlink, "input"),
    "hard link to the input": (_hardlink, "input"),
    "FIFO": (_fifo, "FIFO"),
    "character device": (_chardev, "character device"),
    "existing folder": (_folder, "folder"),
    "read-only folder": (_read_only_folder, "not writable"),
}


def _setup(command, tmp_path, record_bytes, aircraft_bytes):
    """(input path, argv without -o) of ``command`` in ``tmp_path``."""
    if command == "fit":
        inp = tmp_path / "rec.csv"
        inp.write_bytes(record_bytes)
        return inp, ["fit", str(inp), *FIT]
    inp = tmp_path / "plane.json"
    inp.write_bytes(aircraft_bytes)
    return inp, ["simulate", "--aircraft", str(inp), "--model", "steady", "--duration", "2"]


@pytest.mark.parametrize("command", ["fit", "simulate"])
@pytest.mark.parametrize("case", list(CASES))
def test_unsafe_output_is_refused(case, command, tmp_path, capsys, record_bytes, aircraft_bytes):
    make, reason = CASES[case]
    inp, argv = _setup(command, tmp_path, record_bytes, aircraft_bytes)
    out = make(tmp_path, inp)
    before_in = _fingerprint(inp)
    before_out = os.lstat(out) if os.path.lexists(out) else None
    try:
        code = main([*argv, "-o", str(out)])
    finally:
        if case == "read-only folder":
            out.parent.chmod(0o755)
    _, err = capsys.readouterr()
    assert code == 2
    assert err.count("\n") == 1 and str(out) in err and reason in err, err
    assert _fingerprint(inp) == before_in  # the input: same bytes, same inode
    if before_out is not None:  # the output node is what it was (a link stays a link, a FIFO a FIFO)
        after = os.lstat(out)
        assert (after.st_ino, after.st_mode) == (before_out.st_ino, before_out.st_mode)
    assert not _temporaries(tmp_path)
    assert ".tmp" not in err


def test_relative_path_to_the_input_is_refused(tmp_path, capsys, record_bytes, monkeypatch):
    (tmp_path / "sub").mkdir()
    (tmp_path / "rec.csv").write_bytes(record_bytes)
    monkeypatch.chdir(tmp_path / "sub")
    code = main(["fit", "../rec.csv", *FIT, "-o", "./../sub/../rec.csv"])
    assert code == 2 and "./../sub/../rec.csv" in capsys.readouterr().err
    assert (tmp_path / "rec.csv").read_bytes() == record_bytes


# --- the other commands check their outputs before the work -----------------------------------------
@pytest.fixture
def fitted(tmp_path, record_bytes, capsys):
    """(record, result JSON) in tmp_path."""
    rec, res = tmp_path / "rec.csv", tmp_path / "res.json"
    rec.write_bytes(record_bytes)
    assert main(["fit", str(rec), *FIT, "-o", str(res)]) == 0
    capsys.readouterr()
    return rec, res


@pytest.mark.parametrize(
    "argv, victim, reason",
    [
        (["report", "{res}", "-o", "{res}"], "res", "input"),
        (["report", "{res}", "-o", "{rec}"], "rec", "not a folder"),
        (["batch", "{dir}", *FIT, "--serial", "--no-progress", "--output", "{dir}"], "dir", "input"),
        (["batch", "{rec}", *FIT, "--serial", "--no-progress", "--output", "{rec}"], "rec", "input"),
        (["diagnose", "{rec}", "--aircraft", "navion", "--figure", "{rec}"], "rec", "input"),
        (["diagnose", "{rec}", "--aircraft", "navion", "-o", "{res}", "--figure", "{rec}"], "rec", "input"),
        (["montecarlo", "--aircraft", "navion", "--model", "steady", "-n", "2", "-o", "{rec}"], "rec", "not a folder"),
        (["demo", "-o", "{rec}"], "rec", "not a folder"),
    ],
)
def test_every_command_checks_before_working(argv, victim, reason, fitted, tmp_path, capsys):
    rec, res = fitted
    names = {"rec": str(rec), "res": str(res), "dir": str(tmp_path)}
    before = {k: _fingerprint(p) for k, p in (("rec", rec), ("res", res))}
    code = main([a.format(**names) for a in argv])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and names[victim] in err and reason in err, err
    assert {k: _fingerprint(p) for k, p in (("rec", rec), ("res", res))} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.csv", "res.json"]  # nothing written


def test_batch_refuses_a_record_named_like_its_table(tmp_path, record_bytes, capsys):
    src = tmp_path / "out"
    src.mkdir()
    (src / "table.csv").write_bytes(record_bytes)  # a record that the table would replace
    code = main(["batch", str(src / "table.csv"), *FIT, "--serial", "--no-progress", "--output", str(src)])
    assert code == 2 and "table.csv" in capsys.readouterr().err
    assert (src / "table.csv").read_bytes() == record_bytes and not (src / "results").exists()


# --- overwriting, modes, links --------------------------------------------------------------------------
def test_overwriting_an_earlier_result_works(fitted, capsys):
    rec, res = fitted
    first = json.loads(res.read_text())
    res.write_text("stale")  # an earlier (here: spoiled) result of fdml's own is replaced
    assert main(["fit", str(rec), *FIT, "-o", str(res)]) == 0
    again = json.loads(res.read_text())
    assert again["format"] == "fdml.FitResult" and again["values"] == first["values"]  # same fit, same numbers
    assert not _temporaries(res.parent)


@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_new_files_respect_the_umask(tmp_path, mask, mode):
    old = os.umask(mask)
    try:
        p = outputs.atomic_write_text(tmp_path / "new.txt", "x")
        fig = _figure()
        q = outputs.atomic_savefig(fig, tmp_path / "new.png")
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(p).st_mode) == mode
    assert stat.S_IMODE(os.stat(q).st_mode) == mode


def test_replacing_keeps_the_mode_of_the_file(tmp_path):
    p = tmp_path / "old.txt"
    p.write_text("old")
    p.chmod(0o640)
    outputs.atomic_write_text(p, "new")
    assert p.read_text() == "new" and stat.S_IMODE(os.stat(p).st_mode) == 0o640


def test_symlink_to_a_regular_file_is_kept_and_its_target_written(tmp_path):
    target = tmp_path / "real.json"
    target.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(target.name)
    outputs.atomic_write_text(link, "new")
    assert link.is_symlink() and target.read_text() == "new"
    assert not _temporaries(tmp_path)


def test_text_is_written_verbatim_as_utf8(tmp_path):
    text = "α, q\r\nΔ\n"
    p = outputs.atomic_write_text(tmp_path / "t.txt", text)
    assert p.read_bytes() == text.encode("utf-8")
    assert outputs.atomic_write_bytes(tmp_path / "b.bin", b"\x00\xff").read_bytes() == b"\x00\xff"
    with outputs.atomic_open(tmp_path / "o.txt") as fh:
        fh.write("line\n")
        assert not (tmp_path / "o.txt").exists()  # nothing at the path before the block ends
    assert (tmp_path / "o.txt").read_text() == "line\n"


def test_missing_parent_folders_are_created(tmp_path):
    p = outputs.atomic_write_text(tmp_path / "a" / "b" / "c.txt", "x")
    assert p.read_text() == "x"


def test_parent_that_is_a_file_is_refused(tmp_path):
    (tmp_path / "f").write_text("keep")
    with pytest.raises(OutputError, match="is not a folder"):
        outputs.atomic_write_text(tmp_path / "f" / "x.txt", "x")
    assert (tmp_path / "f").read_text() == "keep"


# --- failing writes: the previous file stays, no temporary, the user's path in the message ----------
class _FailingFile:
    """A file object that fails with ENOSPC once ``limit`` bytes are written (a full disk)."""

    def __init__(self, fh, limit):
        self._fh, self._left = fh, limit

    def write(self, data):
        n = len(data)
        if n > self._left:
            self._fh.write(data[: self._left])
            self._left = 0
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self._left -= n
        return self._fh.write(data)

    def __getattr__(self, name):
        return getattr(self._fh, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._fh.close()
        return False


def _full_disk_after(monkeypatch, limit):
    real = os.fdopen
    monkeypatch.setattr(os, "fdopen", lambda *a, **k: _FailingFile(real(*a, **k), limit))


def _enospc(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(args[0]))


@pytest.mark.parametrize("where", ["rename", "write"])
def test_full_disk_leaves_the_previous_result(where, fitted, monkeypatch, capsys):
    rec, res = fitted
    before = res.read_bytes()
    if where == "rename":
        monkeypatch.setattr(os, "replace", _enospc)
    else:
        _full_disk_after(monkeypatch, 100)
    code = main(["fit", str(rec), *FIT, "-o", str(res)])
    err = capsys.readouterr().err
    assert code == 2 and str(res) in err and "No space left on device" in err
    assert ".tmp" not in err  # never the hidden temporary file's name
    assert res.read_bytes() == before and not _temporaries(res.parent)


def test_unwritable_folder_on_write_is_an_output_error(tmp_path, monkeypatch):
    # as root os.access lets everything through: the real EACCES/EROFS comes at mkstemp
    def refuse(*a, **k):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(tmp_path / ".x.tmp"))

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    with pytest.raises(OutputError) as e:
        outputs.atomic_write_text(tmp_path / "r.json", "{}")
    assert str(tmp_path / "r.json") in str(e.value) and "Read-only file system" in str(e.value)
    assert ".tmp" not in str(e.value)


def _figure():
    from matplotlib.figure import Figure

    fig = Figure(figsize=(3, 2))
    fig.subplots().plot([0, 1, 2], [1, 0, 1])
    return fig


def test_failed_figure_leaves_no_truncated_png(tmp_path, monkeypatch):
    png = tmp_path / "fig.png"
    outputs.atomic_savefig(_figure(), png, dpi=50)
    before = png.read_bytes()
    assert before.startswith(b"\x89PNG")
    _full_disk_after(monkeypatch, 200)  # the disk fills after 200 bytes of the new figure
    with pytest.raises(OutputError, match="No space left on device") as e:
        outputs.atomic_savefig(_figure(), png, dpi=80)
    assert str(png) in str(e.value)
    assert png.read_bytes() == before and not _temporaries(tmp_path)
    monkeypatch.undo()
    _full_disk_after(monkeypatch, 200)
    with pytest.raises(OutputError):
        outputs.atomic_savefig(_figure(), tmp_path / "new.png")
    assert not (tmp_path / "new.png").exists() and not _temporaries(tmp_path)


def test_figure_format_comes_from_the_final_name(tmp_path):
    p = outputs.atomic_savefig(_figure(), tmp_path / "f.svg")
    assert b"<svg" in p.read_bytes()[:500]


def test_report_write_failing_leaves_no_report(fitted, monkeypatch, capsys):
    _, res = fitted
    _full_disk_after(monkeypatch, 1000)
    out = res.parent / "rep"
    code = main(["report", str(res), "-o", str(out)])
    assert code == 2 and str(out / "spectra.png") in capsys.readouterr().err
    assert not out.exists() or not list(out.iterdir())  # no figure, no temporary, no report.md


def test_staged_outputs_appear_together(tmp_path):
    with pytest.raises(RuntimeError), outputs.StagedOutputs() as out:
        out.write_text(tmp_path / "a.txt", "a")
        raise RuntimeError("drawing failed")
    assert not list(tmp_path.iterdir())
    with outputs.StagedOutputs() as out:
        out.write_text(tmp_path / "a.txt", "a")
        assert not (tmp_path / "a.txt").exists()
        out.write_text(tmp_path / "b.txt", "b")
    assert (tmp_path / "a.txt").read_text() + (tmp_path / "b.txt").read_text() == "ab"


def test_check_output_dir_refuses_a_file_and_accepts_a_folder(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        outputs.check_output_dir(tmp_path / "f")
    assert outputs.check_output_dir(tmp_path) == tmp_path
    assert outputs.check_output_dir(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"


# --- a closed pipe ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("how", ["closed before the output", "closed after one line"])
def test_closed_pipe_ends_quietly(how, tmp_path, record_bytes):
    rec = tmp_path / "rec.csv"
    rec.write_bytes(record_bytes)
    if how == "closed before the output":
        argv = ["fit", str(rec), *FIT, "--json"]
    else:  # about 1.6 MB of JSON, far beyond a pipe's buffer: the writes after the first line fail
        argv = ["response", "--aircraft", "navion", "--model", "steady", "--band", "0.01:100:0.01", "--json"]
    # block-buffered stdout as in a normal shell: with PYTHONUNBUFFERED a large write to a closed
    # pipe can end without an error, and the case would prove nothing
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"} | {"MPLBACKEND": "Agg"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "fdml", *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env
    )
    if how == "closed after one line":
        assert proc.stdout.readline().strip() == b"{"
    proc.stdout.close()  # the reader goes away (`| head -1`)
    err = proc.stderr.read().decode()
    proc.wait(timeout=60)
    assert err == "", err  # no traceback, no "internal error", no "Exception ignored"


# --- property: no output replaces an input -----------------------------------------------------------
KINDS = ("input", "symlink", "hardlink", "symlink chain", "relative", "fresh", "earlier output")
#: Kinds that name the input itself: these must be refused.
SAME = {"input", "symlink", "hardlink", "symlink chain", "relative"}


def _output_for(kind: str, d: Path, inp: Path) -> str:
    if kind == "input":
        return str(inp)
    if kind == "symlink":
        os.symlink(inp, d / "l1")
        return str(d / "l1")
    if kind == "hardlink":
        os.link(inp, d / "h1")
        return str(d / "h1")
    if kind == "symlink chain":
        os.symlink(inp.name, d / "l1")
        os.symlink("l1", d / "l2")
        return str(d / "l2")
    if kind == "relative":
        (d / "sub").mkdir()
        return f"./{os.path.relpath(d)}/sub/./../{inp.name}"
    return str(d / "out.file")


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(command=st.sampled_from(["fit", "simulate"]), kind=st.sampled_from(KINDS))
def test_no_output_replaces_an_input(command, kind, record_bytes, aircraft_bytes, capsys):
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        inp, argv = _setup(command, d, record_bytes, aircraft_bytes)
        out = _output_for(kind, d, inp)
        if kind == "earlier output":
            assert main([*argv, "-o", out]) in (0, 1)
        before = _fingerprint(inp)
        code = main([*argv, "-o", out])
        capsys.readouterr()
        assert code == 2 or _fingerprint(inp) == before
        # stronger than the property: the input is never touched, and only a true input is refused
        assert _fingerprint(inp) == before
        assert (code == 2) == (kind in SAME)
        assert not _temporaries(d)
