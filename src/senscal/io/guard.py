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
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from senscal.errors import InputError

__all__ = ["protect_inputs", "note_input", "check_output", "check_output_dir"]

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
