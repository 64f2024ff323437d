"""Output-path checks shared by every writer: never overwrite an input, clear errors.

While a command runs (:func:`protect_inputs`, entered by ``senscal.cli.main``)
every file a reader opens is remembered; :func:`check_output` refuses to write
over one of them, refuses folders and paths under a file, and turns the
``OSError`` of an unwritable folder into a one-line :class:`InputError`.
Outside a command (plain API use) only the folder checks apply, so a script
may deliberately rewrite a file it read.

``-`` names standard input / output (:data:`STDIO`): readers take a CSV
recording from stdin (:func:`stdin_bytes` reads it once per command), and
:func:`write_bytes`, :func:`write_text` and ``write_recording`` write to
stdout.  Once data went to stdout (:func:`claim_stdout`) it is taken: a
second output there is refused, and the command line sends its messages to
stderr instead (:func:`stdout_claimed`).
"""

from __future__ import annotations

import os
import stat
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from senscal.errors import InputError

__all__ = ["protect_inputs", "note_input", "check_output", "check_output_dir", "atomic_output", "write_text",
           "write_bytes", "STDIO", "is_stdio", "stdin_bytes", "claim_stdout", "stdout_claimed"]

_inputs: set[str] | None = None

#: The file name that means standard input (where read) or standard output (where written).
STDIO = "-"
_stdout_owner: str | None = None
_stdin_data: bytes | None = None
_stdin_owner: str | None = None


def is_stdio(path: str | os.PathLike | None) -> bool:
    """Whether ``path`` is ``-`` (standard input or output)."""
    return path is not None and os.fspath(path) == STDIO


def stdin_bytes(what: str = "input") -> bytes:
    """Standard input, read whole (pipes cannot seek; readers need it twice); once per command.

    Raises
    ------
    InputError
        Standard input is a terminal (nothing piped in) or empty.
    """
    global _stdin_data, _stdin_owner
    if _stdin_owner is not None and _stdin_owner != what and _inputs is not None:
        raise InputError(f"{_stdin_owner} and {what} both read standard input ('-'); give one of them as a file")
    if _stdin_data is not None and _inputs is not None:
        return _stdin_data
    stream = sys.stdin
    if stream is None or (hasattr(stream, "isatty") and stream.isatty()):
        raise InputError(f"{what} '-' means standard input, but nothing is piped in; "
                         "use 'senscal ... - < FILE.csv' or give the file name")
    buf = getattr(stream, "buffer", None)
    data = buf.read() if buf is not None else stream.read().encode("utf-8")
    if not data:
        raise InputError(f"{what} '-' (standard input) is empty; pipe a recording in or give a file name")
    if _inputs is not None:
        _stdin_data, _stdin_owner = data, what
    return data


def claim_stdout(what: str) -> None:
    """Mark standard output as holding ``what`` (data); refuse a second output there.

    Raises
    ------
    InputError
        Something else was already written to stdout by this command.
    """
    global _stdout_owner
    if _stdout_owner is not None and _stdout_owner != what:
        raise InputError(f"{what} and {_stdout_owner} both go to standard output ('-'); send one of them to a file")
    if _inputs is not None:  # only inside a command; a script may write to stdout as often as it likes
        _stdout_owner = what


def stdout_claimed() -> str | None:
    """What the running command wrote to standard output, or None."""
    return _stdout_owner


def _key(path: str | os.PathLike) -> str:
    return os.path.normcase(os.path.realpath(os.fspath(path)))


@contextmanager
def protect_inputs() -> Iterator[None]:
    """Remember the files read inside the block and refuse to overwrite them."""
    global _inputs, _stdout_owner, _stdin_data, _stdin_owner
    saved, _inputs = _inputs, set()
    saved_io = (_stdout_owner, _stdin_data, _stdin_owner)
    _stdout_owner, _stdin_data, _stdin_owner = None, None, None
    try:
        yield
    finally:
        _inputs = saved
        _stdout_owner, _stdin_data, _stdin_owner = saved_io


def note_input(path: str | os.PathLike) -> None:
    """Record ``path`` as an input of the running command."""
    if _inputs is not None:
        _inputs.add(_key(path))


def check_output(path: str | os.PathLike, *, suffixes: tuple[str, ...] | None = None,
                 what: str = "output file") -> Path:
    """Check that ``path`` can be written as an output and create its folder.

    Parameters
    ----------
    path : path-like
        The file about to be written.
    suffixes : tuple of str, optional
        Allowed extensions (lower case, with the dot), e.g. the image formats of a plot.
    what : str
        What the file is, for the error message.

    Returns
    -------
    Path
        ``path`` as a :class:`Path`.
    """
    path = Path(path)
    if is_stdio(path):
        return path  # standard output: nothing to create or protect
    if not path.is_absolute() and len(path.parts) > 1 and path.parts[0] == STDIO:
        raise InputError(f"{what} {path}: '-' means standard output, which takes one file, not a folder of "
                         "files; give a folder name")
    if path.is_dir():
        raise InputError(f"{what} {path} is a folder; give a file name")
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise InputError(f"{what} {path} has an unsupported extension {path.suffix or '(none)'!r}; "
                         f"use one of {', '.join(sorted(suffixes))}")
    if _inputs is not None and path.exists():
        same = _key(path) in _inputs or any(os.path.exists(p) and os.path.samefile(path, p) for p in _inputs)
        if same:
            raise InputError(f"{what} {path} is also an input of this command; refusing to overwrite it, "
                             f"choose another name")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the folder of {what} {path}: {exc.strerror or exc}") from None
    if not os.access(path.parent, os.W_OK):
        raise InputError(f"cannot write {what} {path}: its folder is not writable")
    return path


def check_output_dir(path: str | os.PathLike, *, what: str = "output folder") -> Path:
    """Create the output folder ``path`` or raise a one-line :class:`InputError`."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"{what} {path} is a file; give a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create {what} {path}: {exc.strerror or exc}") from None
    return path


def _os_reason(exc: OSError) -> str:
    return (exc.strerror or str(exc) or type(exc).__name__).rstrip(".").lower()


@contextmanager
def atomic_output(path: str | os.PathLike, *, what: str = "output file") -> Iterator[Path]:
    """Write an output file all at once: yield a temporary path, then rename it over ``path``.

    Callers write the whole file to the yielded path (same folder and
    extension, so libraries that pick the format from the extension still
    work).  On success it replaces ``path`` in one rename; on any failure the
    temporary file is removed and ``path`` is left as it was, so a full disk
    or an interrupted run never leaves a half-written result.  Devices and
    pipes (``/dev/null``, ``/dev/full``, a FIFO) are written in place, since
    renaming over them would replace the device.

    Parameters
    ----------
    path : path-like
        The final file; :func:`check_output` should have accepted it.
    what : str
        What the file is, for error messages.

    Yields
    ------
    Path
        Where to write.

    Raises
    ------
    InputError
        The file is read-only, or writing failed (``OSError``: no space,
        permission, quota ...); one line naming the file.
    """
    path = Path(path)
    if is_stdio(path):
        raise InputError(f"{what} cannot be written to standard output ('-'); give a file name")
    try:
        st = os.stat(path)
    except OSError:
        st = None
    if st is not None and stat.S_ISREG(st.st_mode) and not st.st_mode & 0o222:
        # Even root could rename over it; the user made it read-only on purpose.
        raise InputError(f"{what} {path} is read-only; make it writable or choose another name")
    if st is not None and not stat.S_ISREG(st.st_mode):
        try:
            yield path
        except OSError as exc:
            raise InputError(f"cannot write {what} {path}: {_os_reason(exc)}") from None
        return
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}",
                                        dir=path.parent if str(path.parent) else ".")
        os.close(fd)
    except OSError as exc:
        raise InputError(f"cannot write {what} {path}: {_os_reason(exc)}") from None
    tmp = Path(tmp_name)
    try:
        yield tmp
        # mkstemp makes the file private (0600); give it the mode a plain open() would.
        mode = stat.S_IMODE(st.st_mode) if st is not None else 0o666 & ~_umask()
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except OSError as exc:
        _remove(tmp)
        raise InputError(f"cannot write {what} {path}: {_os_reason(exc)}") from None
    except BaseException:
        _remove(tmp)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _remove(path: Path) -> None:
    try:
        path.unlink()
    except OSError:
        pass


def write_text(path: str | os.PathLike, text: str, *, what: str = "output file") -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; see :func:`atomic_output`."""
    return write_bytes(path, text.encode("utf-8"), what=what)


def write_bytes(path: str | os.PathLike, data: bytes, *, what: str = "output file") -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_output`); ``-`` writes to standard output."""
    path = Path(path)
    if is_stdio(path):
        claim_stdout(what)
        out = getattr(sys.stdout, "buffer", None)
        if out is not None:
            sys.stdout.flush()
            out.write(data)
            out.flush()
        else:
            sys.stdout.write(data.decode("utf-8"))
            sys.stdout.flush()
        return path
    with atomic_output(path, what=what) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
    return path
