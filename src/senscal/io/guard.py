"""Output-path checks shared by every writer: never overwrite an input, clear errors.

While a command runs (:func:`protect_inputs`, entered by ``senscal.cli.main``)
every file a reader opens is remembered; :func:`check_output` refuses to write
over one of them, refuses folders and paths under a file, and turns the
``OSError`` of an unwritable folder into a one-line :class:`InputError`.
Outside a command (plain API use) only the folder checks apply, so a script
may deliberately rewrite a file it read.

The command line declares the files a command will write before it runs
(:func:`declare_outputs`, from the command's ``--out``/``--plot``/...
options): each is checked then (folder, not an input named on the command
line, no two outputs on one file), and :func:`atomic_output` holds each
declared file back as a finished temporary file until the command ends.
Only then, with every input known (a recording named inside a run file, a
registry, a batch glob), are they checked against the inputs once more and
renamed into place together: a command that fails writes none of them.
A missing folder is refused unless the user asked for it with ``--mkdir``
(:func:`allow_new_folders`): a typo in a folder name must not silently grow
a new tree.

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
           "write_bytes", "STDIO", "is_stdio", "stdin_bytes", "claim_stdout", "stdout_claimed", "declare_outputs",
           "allow_new_folders", "commit_outputs", "discard_outputs", "make_parent_folder"]

_inputs: set[str] | None = None
# Files the running command declared as its outputs (key -> what) and, of those, the ones that are read
# and then replaced by design (a drift --state): written at once, never held back.
_declared: dict[str, str] = {}
_updated: set[str] = set()
# Declared outputs written to a temporary file and waiting for the command to end: (tmp, final, what).
_pending: list[tuple[Path, Path, str]] = []
_new_folders = False
# Output folders the command line named (kind "folder"): created, with whatever the command puts inside.
_folders: set[str] = set()
# Folders a command reads and updates in place by design (a drift-fleet state store): files in them may be
# replaced although they were read.
_update_folders: set[str] = set()

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


def allow_new_folders(flag: bool = True) -> None:
    """Let the running command create missing folders of its outputs (``--mkdir``)."""
    global _new_folders
    _new_folders = bool(flag)


def _keeps_outputs(exc: BaseException | None) -> bool:
    # Success, a --strict diagnostic (the result stays for inspection) or a clean exit keep the outputs.
    if exc is None:
        return True
    from senscal.errors import DiagnosticError

    if isinstance(exc, DiagnosticError):
        return True
    if isinstance(exc, SystemExit):
        return exc.code in (0, None)
    return type(exc).__name__ == "Exit" and getattr(exc, "exit_code", 1) == 0  # click.exceptions.Exit


@contextmanager
def protect_inputs() -> Iterator[None]:
    """Remember the files read inside the block and refuse to overwrite them.

    Declared outputs (:func:`declare_outputs`) written inside the block are
    renamed into place when it ends without an error (or with a ``--strict``
    diagnostic); after any other error none of them is written.
    """
    global _inputs, _stdout_owner, _stdin_data, _stdin_owner, _declared, _updated, _pending, _new_folders, \
        _folders, _update_folders
    import threading

    # A job run in a worker thread of this process (batch, fit-array with threads) opens its own scope for its
    # inputs; the held-back outputs belong to the command in the main thread and stay where they are.
    owner = threading.current_thread() is threading.main_thread()
    saved, _inputs = _inputs, set()
    saved_io = (_stdout_owner, _stdin_data, _stdin_owner)
    saved_out = (_declared, _updated, _pending, _new_folders, _folders, _update_folders)
    _stdout_owner, _stdin_data, _stdin_owner = None, None, None
    if owner:
        _declared, _updated, _pending, _folders, _update_folders = {}, set(), [], set(), set()
    try:
        try:
            yield
        except BaseException as exc:
            if owner:
                if _keeps_outputs(exc):
                    commit_outputs()
                else:
                    discard_outputs()
            raise
        if owner:
            commit_outputs()
    finally:
        if owner:
            discard_outputs()
            _declared, _updated, _pending, _new_folders, _folders, _update_folders = saved_out
        _inputs = saved
        _stdout_owner, _stdin_data, _stdin_owner = saved_io


def declare_outputs(outputs: dict[str, tuple[str, str]], inputs: dict[str, str] | None = None) -> None:
    """Check every output of the running command before it starts, and hold them back until it ends.

    Parameters
    ----------
    outputs : dict
        ``{path: (what, kind)}``: ``kind`` is ``"file"`` (written once, at
        the end), ``"update"`` (read and replaced by design, e.g. a drift
        state: written when the command writes it), ``"folder"`` (a folder of
        outputs) or ``"update-folder"`` (a folder whose files are read and
        replaced by design, e.g. a fleet state store).
    inputs : dict, optional
        ``{path: what}`` of the files named on the command line.

    Raises
    ------
    InputError
        An output names an input, two outputs name one file, a file output is
        a folder (or a folder output a file), or its folder is missing (without
        ``--mkdir``) or not writable; one line naming the options.
    """
    inputs = dict(inputs or {})
    seen: dict[str, str] = {}
    for raw, (what, kind) in outputs.items():
        path = Path(raw)
        if is_stdio(path):
            continue  # standard output; a command that writes a folder refuses it (check_output_dir)
        key = _key(path)
        if key in seen:
            raise InputError(f"{what} and {seen[key]} name the same file {raw}; give each its own name")
        seen[key] = what
        for other, owhat in inputs.items():
            if not is_stdio(other) and _same_file(path, Path(other)):
                raise InputError(f"{what} {raw} is also an input of this command"
                                 f"{'' if owhat == 'input' else f' ({owhat})'}; refusing to overwrite it, choose "
                                 "another name")
        if kind in ("folder", "update-folder"):
            check_output_dir(path, what=what, create=False)
            if _inputs is not None:
                _folders.add(key)
                if kind == "update-folder":
                    _update_folders.add(key)
            continue
        check_output(path, what=what)
        if _inputs is not None:
            _declared[key] = what
            if kind == "update":
                _updated.add(key)


def _same_file(a: Path, b: Path) -> bool:
    if _key(a) == _key(b):
        return True
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _is_input(path: Path) -> bool:
    """Whether ``path`` is a file the running command read (and may not replace)."""
    if _inputs is None or not path.exists():
        return False
    if _key(path) in _updated or any(_key(p) in _update_folders for p in path.parents):
        return False  # read and replaced by design
    return _key(path) in _inputs or any(os.path.exists(p) and os.path.samefile(path, p) for p in _inputs)


def commit_outputs() -> None:
    """Rename the held-back outputs into place, after checking them against every input now known.

    Raises
    ------
    InputError
        One of them names a file the command read (found only while it ran,
        e.g. a recording listed in a run file); then none is written.
    """
    global _pending
    pending, _pending = _pending, []
    try:
        for tmp, final, what in pending:
            if _key(final) not in _updated and _is_input(final):
                raise InputError(f"{what} {final} is also an input of this command; refusing to overwrite it, "
                                 "choose another name (nothing was written)")
        for i, (tmp, final, what) in enumerate(pending):
            try:
                os.replace(tmp, final)
            except OSError as exc:
                raise InputError(f"cannot write {what} {final}: {_os_reason(exc)}") from None
            pending[i] = (final, final, what)  # renamed: no longer ours to remove
    finally:
        for tmp, final, _ in pending:
            if tmp != final:
                _remove(tmp)


def discard_outputs() -> None:
    """Remove the held-back outputs of a command that failed: it writes none of its files."""
    global _pending
    pending, _pending = _pending, []
    for tmp, _, _ in pending:
        _remove(tmp)


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
    if _key(path) not in _updated and _is_input(path):
        raise InputError(f"{what} {path} is also an input of this command; refusing to overwrite it, "
                         f"choose another name")
    _make_parent(path, what)
    if not os.access(path.parent, os.W_OK):
        raise InputError(f"cannot write {what} {path}: its folder is not writable")
    return path


def make_parent_folder(path: str | os.PathLike, what: str = "output file") -> None:
    """Create the folder a file is written in: inside a command only with ``--mkdir`` (else one line)."""
    _make_parent(Path(path), what)


def _make_parent(path: Path, what: str) -> None:
    """Create the folder ``path`` goes in: always outside a command, inside one only with ``--mkdir``."""
    parent = path.parent
    if parent.is_dir():
        return
    missing = next((p for p in reversed((parent, *parent.parents)) if not p.exists()), parent)
    named = any(_key(p) in _folders for p in (parent, *parent.parents))  # inside a folder the user named
    if _inputs is not None and not _new_folders and not named:
        if missing.parent.exists() and not missing.parent.is_dir():
            raise InputError(f"cannot write {what} {path}: {missing.parent} is a file, not a folder")
        raise InputError(f"the folder {parent} of {what} {path} does not exist ({missing} is missing); create it "
                         "or add --mkdir to have it created")
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the folder of {what} {path}: {exc.strerror or exc}") from None


def check_output_dir(path: str | os.PathLike, *, what: str = "output folder", create: bool = True) -> Path:
    """Create the output folder ``path`` (its parent must exist inside a command) or raise a one-line error.

    ``create=False`` checks only (the command creates it when it writes).
    """
    path = Path(path)
    if is_stdio(path):
        raise InputError(f"{what} '-' means standard output, which takes one file, not a folder of files; "
                         "give a folder name")
    if path.exists() and not path.is_dir():
        raise InputError(f"{what} {path} is a file; give a folder")
    if path.is_dir():
        return path
    _make_parent(path, what)
    if not os.access(path.parent, os.W_OK):
        raise InputError(f"cannot create {what} {path}: its folder {path.parent} is not writable")
    if create:
        try:
            path.mkdir(exist_ok=True)
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
    key = _key(path)
    if key not in _updated and _is_input(path):
        # The last line of defence: whatever a command checked before it read its inputs, no write may
        # replace a file it read (allan checked its --out before the recording was known, and replaced it).
        raise InputError(f"{what} {path} is also an input of this command; refusing to overwrite it, "
                         "choose another name")
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
        if _inputs is not None and key in _declared and key not in _updated:
            # A declared output: held back until the command ends (all or none); a second write replaces it.
            for i, (old, final, _) in enumerate(_pending):
                if _key(final) == key:
                    _remove(old)
                    del _pending[i]
                    break
            _pending.append((tmp, path, what))
            return
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
