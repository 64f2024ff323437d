"""Output-path checks shared by every writer: never overwrite an input, clear errors.

While a command runs (:func:`protect_inputs`, entered by ``senscal.cli.main``)
every file a reader opens is remembered; :func:`check_output` refuses to write
over one of them, refuses folders and paths under a file, and turns the
``OSError`` of an unwritable folder into a one-line :class:`InputError`.
Outside a command (plain API use) only the folder checks apply, so a script
may deliberately rewrite a file it read.
"""

from __future__ import annotations

import os
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from senscal.errors import InputError

__all__ = ["protect_inputs", "note_input", "check_output", "check_output_dir", "atomic_output", "write_text",
           "write_bytes"]

_inputs: set[str] | None = None


def _key(path: str | os.PathLike) -> str:
    return os.path.normcase(os.path.realpath(os.fspath(path)))


@contextmanager
def protect_inputs() -> Iterator[None]:
    """Remember the files read inside the block and refuse to overwrite them."""
    global _inputs
    saved, _inputs = _inputs, set()
    try:
        yield
    finally:
        _inputs = saved


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
    """Write ``data`` to ``path`` atomically; see :func:`atomic_output`."""
    path = Path(path)
    with atomic_output(path, what=what) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
    return path
