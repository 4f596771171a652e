"""Safe output files: never an input, never a device, always written atomically.

Every file fdml writes (results, records, reports, figures, batch tables) goes
through this module, so there is one implementation of the rules:

* an output that is one of the command's inputs (the same file after resolving
  symbolic and hard links, :func:`os.path.samefile`) is refused;
* an output that exists and is not a regular file (a folder, a device node, a
  FIFO, a socket) is refused; a folder output (``check_output_dir``) must be a
  folder;
* an output whose folder is a file or cannot be written is refused;
* the content is written to a temporary file in the same folder
  (``.NAME.XXXXXXXX.tmp``) and renamed into place, so a reader never sees a
  half-written file and a failure (full disk, read-only file system) leaves the
  previous file untouched and no temporary file behind;
* a symbolic link to a regular file is kept: the new content lands at its target;
* the new file gets the mode of the file it replaces, or ``0o666`` less the umask.

Every refusal and every failed write is an :class:`~fdml.errors.OutputError`
whose message names the path the user gave and the reason, never the hidden
temporary file.  Overwriting an earlier regular file (fdml's own previous
result) is allowed.

:class:`StagedOutputs` writes several files that appear together (a report's
figures and its Markdown page): nothing is renamed into place until all of
them are written.
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from .errors import OutputError

__all__ = [
    "check_output",
    "check_output_dir",
    "check_output_folder",
    "atomic_write_text",
    "atomic_write_bytes",
    "atomic_open",
    "atomic_savefig",
    "StagedOutputs",
    "Inputs",
]

#: Suffix of the temporary files (``fdml.batch`` removes ``.*.tmp`` left by a crash).
TMP_SUFFIX = ".tmp"


# --- checks -------------------------------------------------------------------------------------
#: Plain-language names of the file types that are not regular files.
_KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
)


def _kind(mode: int) -> str:
    """A plain-language name of a non-regular file type."""
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def _input_paths(inputs) -> list:
    """The path-like entries of ``inputs`` (a preset name or an in-memory object is skipped)."""
    if isinstance(inputs, Inputs):
        return list(inputs.paths)
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    return [p for p in inputs or () if isinstance(p, (str, os.PathLike))]


def _file_id(path) -> tuple[int, int] | None:
    """``(device, inode)`` of ``path`` (links followed), None when it cannot be read."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return st.st_dev, st.st_ino


class Inputs:
    """A command's input files, identified once by device and inode (what :func:`os.path.samefile` compares).

    Pass it as ``inputs`` when many outputs are checked against many inputs
    (a batch): each check is then one ``stat`` of the output.

    Parameters
    ----------
    paths : iterable of str or Path
        Inputs; entries that are not paths or do not exist are skipped.
    """

    def __init__(self, paths: Iterable = ()):
        self.paths = tuple(_input_paths(paths))
        self.ids: dict[tuple[int, int], str] = {}
        for p in self.paths:
            key = _file_id(p)
            if key is not None:  # missing (a preset name) or unreadable: cannot be written over
                self.ids.setdefault(key, str(p))

    def match(self, path) -> str | None:
        """The input (as given) that is the same file or folder as ``path`` (links followed), else None.

        Parameters
        ----------
        path : str or Path
            The file or folder to look up.

        Returns
        -------
        str or None
            The matching input as given, or None.
        """
        key = _file_id(path)
        return None if key is None else self.ids.get(key)


def _same_as_input(path: Path, inputs) -> str | None:
    """The input (as given) that is the same file or folder as ``path``, else None."""
    return (inputs if isinstance(inputs, Inputs) else Inputs(inputs)).match(path)


def _target(path: Path) -> Path:
    """Where a write to ``path`` lands: the end of its symlink chain, or ``path`` itself."""
    return Path(os.path.realpath(path)) if os.path.islink(path) else path


def _check_folder(path: Path, user: str, what: str) -> None:
    """The nearest existing folder above ``path`` must be a folder we can write into."""
    anc = path.parent
    while not os.path.lexists(anc) and anc != anc.parent:
        anc = anc.parent
    if not anc.is_dir():
        raise OutputError(f"{what} {user}: {anc} is not a folder")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise OutputError(f"{what} {user}: folder {anc} is not writable")


def _stat(path: Path, user: str, what: str) -> os.stat_result | None:
    """``os.stat(path)`` (links followed), None when nothing is there."""
    try:
        return os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        return None
    except OSError as exc:  # a symlink loop, a folder we may not search
        raise OutputError(f"{what} {user}: cannot inspect it: {exc.strerror or exc}") from None


def check_output(path, inputs: Iterable | Inputs = (), *, what: str = "output file", folder: bool = False) -> Path:
    """Refuse an output path that would destroy what the user owns.

    Parameters
    ----------
    path : str or Path
        The output as the user gave it.
    inputs : iterable of str or Path, optional
        The files (or folders) the command reads: record files, the aircraft
        JSON, the result JSON.  Entries that are not paths, or do not exist
        (a preset name), are skipped.
    what : str, optional
        What the output is, for the message ("result file", "figure", ...).
    folder : bool, optional
        The output is a folder (created if missing): an existing regular file
        there is refused instead of an existing folder.

    Returns
    -------
    Path
        Where the output is written: ``path``, or the target of ``path`` when
        it is a symbolic link to a regular file (the link is kept).

    Raises
    ------
    OutputError
        The output is one of the inputs (symbolic or hard link included); it
        exists and is not a regular file (not a folder, for ``folder=True``);
        its folder is a file or is not writable.
    """
    user = str(path)
    p = Path(path)
    same = _same_as_input(p, inputs)
    if same is not None:
        which = "" if same == user else f" (the same file as {same})"
        raise OutputError(
            f"{what} {user} is an input of this command{which}; fdml never writes over its inputs: give another name"
        )
    st = _stat(p, user, what)
    if folder:
        if st is not None and not stat.S_ISDIR(st.st_mode):
            kind = "a file" if stat.S_ISREG(st.st_mode) else _kind(st.st_mode)
            raise OutputError(f"{what} {user} is {kind}, not a folder: give a folder name")
        if st is None:
            _check_folder(_target(p), user, what)
        elif not os.access(p, os.W_OK | os.X_OK):
            raise OutputError(f"{what} {user}: folder is not writable")
        return p
    if st is not None and not stat.S_ISREG(st.st_mode):
        if stat.S_ISDIR(st.st_mode):
            raise OutputError(f"{what} {user} is a folder: give a file name")
        raise OutputError(f"{what} {user} is {_kind(st.st_mode)}, not a regular file: give a file name")
    target = _target(p)
    _check_folder(target, user, what)
    return target


def check_output_dir(path, inputs: Iterable | Inputs = (), *, what: str = "output folder") -> Path:
    """:func:`check_output` for a folder output (``folder=True``); returns ``Path(path)``.

    Parameters
    ----------
    path : str or Path
        The output folder as the user gave it.
    inputs : iterable of str or Path, or Inputs, optional
        The command's inputs, which the output may not replace (see :func:`check_output`).
    what : str, optional
        What the output is, for the message.

    Returns
    -------
    Path
        ``Path(path)``.
    """
    return check_output(path, inputs, what=what, folder=True)


def check_output_folder(
    folder, files: Mapping[str, str], inputs: Iterable | Inputs = (), *, what: str = "output folder"
) -> Path:
    """Check an output folder and the files it will hold, before any work; returns ``Path(folder)``.

    Parameters
    ----------
    folder : str or Path
        The output folder as the user gave it.
    files : mapping of str to str
        Each file's name inside ``folder`` -> what it is, for the message.
    inputs : iterable of str or Path, or Inputs, optional
        The command's inputs, which no output may replace (see :func:`check_output`).
    what : str, optional
        What the folder is, for the message.

    Returns
    -------
    Path
        ``Path(folder)``.
    """
    out = check_output_dir(folder, inputs, what=what)
    for name, file_what in files.items():
        check_output(out / name, inputs, what=file_what)
    return out


# --- writing ------------------------------------------------------------------------------------
def _umask() -> int:
    """The process umask, read without changing it where the system allows (Linux)."""
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # elsewhere the only portable way: set and restore at once
    os.umask(mask)
    return mask


def _reason(exc: BaseException) -> str:
    """An OSError's reason without its file names (one of them is the temporary file)."""
    return getattr(exc, "strerror", None) or type(exc).__name__


def _remove(path: Path) -> None:
    with contextlib.suppress(OSError):
        os.unlink(path)


@dataclass(frozen=True)
class _Pending:
    """A temporary file waiting to be renamed to ``final``; ``user`` is the path as given."""

    user: str
    what: str
    final: Path
    tmp: Path

    def error(self, exc: BaseException) -> OutputError:
        return OutputError(f"cannot write {self.what} {self.user}: {_reason(exc)}")


class StagedOutputs:
    """Several output files renamed into place together, once all are written.

    Use as a context manager: on a clean exit every file is renamed into place
    (:meth:`commit`); on an exception every temporary file is removed and no
    previous file is touched.

    Parameters
    ----------
    inputs : iterable of str or Path, optional
        The command's inputs; no output may be one of them.

    Examples
    --------
    >>> with StagedOutputs(inputs=[result_json]) as out:      # doctest: +SKIP
    ...     out.savefig(fig, folder / "spectra.png", dpi=110)
    ...     out.write_text(folder / "report.md", text)
    """

    def __init__(self, inputs: Iterable | Inputs = ()):
        self.inputs = inputs if isinstance(inputs, Inputs) else Inputs(inputs)
        self._pending: list[_Pending] = []

    # -- staging --
    def _stage(self, path, what: str) -> tuple[_Pending, int, int]:
        """A temporary file for ``path``: its pending rename, its descriptor and the mode it gets."""
        final = check_output(path, self.inputs, what=what)
        try:
            final.parent.mkdir(parents=True, exist_ok=True)
            try:
                mode = stat.S_IMODE(os.stat(final).st_mode) & 0o777
            except FileNotFoundError:
                mode = 0o666 & ~_umask()
            fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=TMP_SUFFIX, dir=final.parent)
        except OSError as exc:
            raise OutputError(f"cannot write {what} {path}: {_reason(exc)}") from None
        return _Pending(str(path), what, final, Path(tmp)), fd, mode

    @contextlib.contextmanager
    def open(self, path, mode: str = "w", *, encoding: str = "utf-8", what: str = "output file") -> Iterator:
        """A file handle (``"w"`` text, ``"wb"`` binary) whose content is staged for ``path``.

        Parameters
        ----------
        path : str or Path
            Where the output goes.
        mode : {"w", "wt", "wb"}, optional
            Text (no newline translation) or binary.
        encoding : str, optional
            The text encoding (default UTF-8); unused for binary.
        what : str, optional
            What the output is, for the messages.

        Yields
        ------
        file object
            Write the content to it.
        """
        if mode not in ("w", "wt", "wb"):
            raise ValueError(f"mode must be 'w' or 'wb', got {mode!r}")
        pending, fd, perms = self._stage(path, what)
        try:
            kw: dict[str, Any] = {} if "b" in mode else {"encoding": encoding, "newline": ""}
            try:
                fh = os.fdopen(fd, mode, **kw)
            except BaseException:
                os.close(fd)
                raise
            with fh:
                os.fchmod(fd, perms)
                yield fh
        except BaseException as exc:
            _remove(pending.tmp)
            if isinstance(exc, OSError):
                raise pending.error(exc) from None
            raise
        self._pending.append(pending)

    def write_bytes(self, path, data: bytes, *, what: str = "output file") -> Path:
        """Stage ``data`` for ``path``; returns ``Path(path)``.

        Parameters
        ----------
        path : str or Path
            Where the output goes.
        data : bytes
            The content.
        what : str, optional
            What the output is, for the messages.

        Returns
        -------
        Path
            ``Path(path)``.
        """
        with self.open(path, "wb", what=what) as fh:
            fh.write(data)
        return Path(path)

    def write_text(self, path, text: str, *, encoding: str = "utf-8", what: str = "output file") -> Path:
        """Stage ``text`` for ``path`` (no newline translation); returns ``Path(path)``.

        Parameters
        ----------
        path : str or Path
            Where the output goes.
        text : str
            The content.
        encoding : str, optional
            The text encoding (default UTF-8).
        what : str, optional
            What the output is, for the messages.

        Returns
        -------
        Path
            ``Path(path)``.
        """
        with self.open(path, "w", encoding=encoding, what=what) as fh:
            fh.write(text)
        return Path(path)

    def savefig(self, fig, path, *, what: str = "figure", close: bool = False, **savefig_kwargs) -> Path:
        """Stage ``fig.savefig`` for ``path``; the format comes from ``path``'s suffix unless given.

        Parameters
        ----------
        fig : matplotlib.figure.Figure or callable
            The figure to save, or a function of no arguments that draws it: matplotlib
            is then switched to the non-interactive Agg backend first, and the figure
            is closed after saving.
        path : str or Path
            Where the output goes.
        what : str, optional
            What the output is, for the messages.
        close : bool, optional
            Close the figure after saving (or failing to), as a drawn one always is.
        **savefig_kwargs
            Passed to :meth:`matplotlib.figure.Figure.savefig` (``dpi``, ``format``, ...).

        Returns
        -------
        Path
            ``Path(path)``.
        """
        if callable(fig):
            import matplotlib

            matplotlib.use("Agg")
            fig, close = fig(), True
        fmt = savefig_kwargs.pop("format", None) or Path(path).suffix[1:].lower() or None
        try:
            with self.open(path, "wb", what=what) as fh:
                fig.savefig(fh, format=fmt, **savefig_kwargs)
        finally:
            if close:
                import matplotlib.pyplot as plt

                plt.close(fig)
        return Path(path)

    # -- finishing --
    def commit(self) -> None:
        """Rename every staged file into place (in staging order)."""
        pending, self._pending = self._pending, []
        for i, p in enumerate(pending):
            try:
                with contextlib.suppress(FileNotFoundError, NotADirectoryError):
                    mode = os.stat(p.final).st_mode
                    if not stat.S_ISREG(mode):  # appeared while we wrote
                        raise OutputError(f"{p.what} {p.user} is {_kind(mode)}, not a regular file: give a file name")
                os.replace(p.tmp, p.final)
            except (OSError, OutputError) as err:
                for q in pending[i:]:
                    _remove(q.tmp)
                raise err if isinstance(err, OutputError) else p.error(err) from None

    def discard(self) -> None:
        """Remove every staged temporary file; nothing at the final paths changes."""
        pending, self._pending = self._pending, []
        for p in pending:
            _remove(p.tmp)

    def __enter__(self) -> "StagedOutputs":
        return self

    def __exit__(self, exc_type, exc, tb) -> Literal[False]:
        if exc_type is None:
            self.commit()
        else:
            self.discard()
        return False


# --- one file at a time -------------------------------------------------------------------------
@contextlib.contextmanager
def atomic_open(
    path, mode: str = "w", *, inputs: Iterable | Inputs = (), encoding: str = "utf-8", what: str = "output file"
) -> Iterator:
    """A file handle whose content appears at ``path`` only when the block succeeds.

    Parameters
    ----------
    path : str or Path
        The file to write.
    mode : {"w", "wb"}
        Text (UTF-8, no newline translation) or binary.
    inputs : iterable of str or Path, optional
        The command's inputs (see :func:`check_output`).
    encoding : str, optional
        Text encoding (mode ``"w"``), default UTF-8.
    what : str, optional
        What the file is, named in an error message.

    Yields
    ------
    file object
        Write the content to it.

    Raises
    ------
    OutputError
        The path is refused by :func:`check_output`, or the write failed (the
        previous file, if any, is left as it was).
    """
    with StagedOutputs(inputs) as out, out.open(path, mode, encoding=encoding, what=what) as fh:
        yield fh


def atomic_write_text(
    path, text: str, *, inputs: Iterable | Inputs = (), encoding: str = "utf-8", what: str = "output file"
) -> Path:
    """Write ``text`` to ``path`` atomically (see :func:`atomic_open`); returns ``Path(path)``.

    Parameters
    ----------
    path : str or Path
        Where the output goes.
    text : str
        The content (no newline translation).
    inputs : iterable of str or Path, or Inputs, optional
        The command's inputs, which the output may not replace (see :func:`check_output`).
    encoding : str, optional
        The text encoding (default UTF-8).
    what : str, optional
        What the output is, for the messages.

    Returns
    -------
    Path
        ``Path(path)``.
    """
    with StagedOutputs(inputs) as out:
        return out.write_text(path, text, encoding=encoding, what=what)


def atomic_write_bytes(path, data: bytes, *, inputs: Iterable | Inputs = (), what: str = "output file") -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_open`); returns ``Path(path)``.

    Parameters
    ----------
    path : str or Path
        Where the output goes.
    data : bytes
        The content.
    inputs : iterable of str or Path, or Inputs, optional
        The command's inputs, which the output may not replace (see :func:`check_output`).
    what : str, optional
        What the output is, for the messages.

    Returns
    -------
    Path
        ``Path(path)``.
    """
    with StagedOutputs(inputs) as out:
        return out.write_bytes(path, data, what=what)


def atomic_savefig(
    fig, path, *, inputs: Iterable | Inputs = (), what: str = "figure", close: bool = False, **savefig_kwargs
) -> Path:
    """``fig.savefig(path, **savefig_kwargs)`` atomically: a failure leaves no truncated figure.

    The format comes from ``path``'s suffix unless ``format=`` is given (the
    temporary file's own suffix is never consulted).

    Parameters
    ----------
    fig : matplotlib.figure.Figure or callable
        The figure, or a function of no arguments that draws it headless (see
        :meth:`StagedOutputs.savefig`).
    path : str or Path
        Where the output goes.
    inputs : iterable of str or Path, or Inputs, optional
        The command's inputs, which the output may not replace (see :func:`check_output`).
    what : str, optional
        What the output is, for the messages.
    close : bool, optional
        Close the figure after saving (or failing to).
    **savefig_kwargs
        Passed to :meth:`matplotlib.figure.Figure.savefig` (``dpi``, ``format``, ...).

    Returns
    -------
    Path
        ``Path(path)``.
    """
    with StagedOutputs(inputs) as out:
        return out.savefig(fig, path, what=what, close=close, **savefig_kwargs)
