"""What every job shares: how it reads a recording; what every result shares: the JSON document, the
registry quantities, a table."""

from __future__ import annotations

import dataclasses
import functools
import inspect
from pathlib import Path
from typing import Any, Callable, ClassVar, Mapping, Sequence

from senscal._result import ResultMixin, to_jsonable
from senscal.errors import InputError
from senscal.quantity import Quantity

__all__ = ["JobResult", "Quantity", "ReadOptions", "read_source", "with_read_options", "source_name", "document_fields",
           "given_or_loaded"]


class JobResult(ResultMixin):
    """Mixin for the frozen dataclass a job returns.

    A subclass is a ``@dataclass(frozen=True)`` with typed fields (the
    numbers, in SI units, with standard uncertainties, k=1) and a
    ``warnings: tuple[str, ...]`` field of named warnings
    (:func:`senscal.diagnostics.named`). It overrides what does not fit the
    defaults:

    - :meth:`to_dict` is *the* JSON document: ``senscal <job> --json``
      prints exactly this, batch rows hold it, the registry keeps it.
    - :meth:`quantities` is what ``--save`` stores in the registry.
    - :meth:`to_dataframe` is one row per channel / point where a table fits.

    Attributes
    ----------
    job : str
        Job name as ``senscal batch --job`` spells it (class attribute).
    """

    job: ClassVar[str] = ""

    def to_dict(self) -> dict[str, Any]:
        """The JSON document of the result (plain Python types, NaN -> None)."""
        return super().to_dict()

    def quantities(self) -> tuple[Quantity, ...]:
        """The quoted quantities (value, standard u, unit, k) the registry stores."""
        return ()

    def to_dataframe(self):
        """One row per quoted quantity: name, value, u, unit, k, U = k*u.

        Jobs with a natural table (channels, frequency points) override this.
        """
        import pandas as pd

        rows = [{"quantity": q.name, "value": float(q.value), "u": float(q.uncertainty), "unit": q.unit,
                 "k": float(q.k), "U": float(q.k) * float(q.uncertainty)} for q in self.quantities()]
        return pd.DataFrame(rows, columns=["quantity", "value", "u", "unit", "k", "U"])

    @property
    def warning_names(self) -> tuple[str, ...]:
        """Names of the named warnings (``coloured-noise``, ...)."""
        from senscal.diagnostics import warning_name

        return tuple(n for n in (warning_name(w) for w in getattr(self, "warnings", ())) if n)


@dataclasses.dataclass(frozen=True)
class ReadOptions:
    """How a job reads a recording file: the reading words every job shares.

    Each job's options class derives from this one, so ``FitOptions(fs=1000.0)``
    and ``DriftOptions(time_unit="ms")`` read the same way; a
    :class:`~senscal.io.Recording` given instead of a path is used as is.

    Attributes
    ----------
    time_column : str
        Name of the time column (s) when reading a file.
    fs : float, optional
        Sample rate in Hz for a file without a time column.
    names : str or tuple of str, optional
        Column names of a text file without header: a comma-separated string
        (as ``--names`` gives it) or a sequence, kept as a tuple.
    time_unit : str, optional
        Unit of a time column whose header gives none (s, ms, us, min).
    skip_rows : int, optional
        Lines to skip before the header of a text file.
    start, stop : float, optional
        Keep only the samples from ``start`` to ``stop`` seconds after the
        recording's first sample (``--start``/``--stop``).
    """

    time_column: str = "t"
    fs: float | None = None
    names: str | tuple[str, ...] | None = None
    time_unit: str | None = None
    skip_rows: int | None = None
    start: float | None = None
    stop: float | None = None

    def __post_init__(self):
        # One spelling of the names: "a,b" (as the command line gives it) and ("a", "b") are the same options.
        if isinstance(self.names, str) or self.names:
            object.__setattr__(self, "names", _split_names(self.names))
        elif self.names is not None:
            object.__setattr__(self, "names", None)  # an empty sequence names no columns

    def read(self, source: Any, *, channels: Sequence[str] | None = None, allow_nan: bool = False,
             time_required: bool = True, job: str | None = None):
        """The :class:`~senscal.io.Recording` of ``source`` read with these options (see :func:`read_source`).

        ``job`` names the job reading it, for the time-base checks; their
        warnings are in the Recording's ``warnings`` (add them to the result
        with :func:`senscal.io.plausibility.merge_time_warnings`).
        """
        return read_source(source, time_column=self.time_column, fs=self.fs, names=self.names, channels=channels,
                           allow_nan=allow_nan, time_unit=self.time_unit, skip_rows=self.skip_rows,
                           time_required=time_required, start=self.start, stop=self.stop, job=job)

    @staticmethod
    def words(params: Mapping[str, Any]) -> dict[str, Any]:
        """The reading fields among a command's keyword parameters (``--fs`` ... as given, others left out)."""
        return {k: params[k] for k in _READ_FIELDS if k in params}


_READ_FIELDS = tuple(f.name for f in dataclasses.fields(ReadOptions))


def with_read_options(builder: Callable[..., Any]) -> Callable[..., Any]:
    """A command's options builder that also takes the reading words (``--time-column``, ``--fs`` ...).

    ``builder(**params)`` turns a command's keyword parameters into the job's
    options from the job's own words only; the wrapped builder copies the
    reading words among ``params`` (:meth:`ReadOptions.words`) into them. Its
    signature lists the reading words too, so that ``senscal batch``, which
    refuses an option the builder does not name, passes them through.
    """
    sig = inspect.signature(builder)

    @functools.wraps(builder)
    def build(**params: Any) -> Any:
        opts = builder(**params)
        words = ReadOptions.words(params)
        return dataclasses.replace(opts, **words) if words else opts

    given = list(sig.parameters.values())
    tail = [p for p in given if p.kind is p.VAR_KEYWORD]
    added = [inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=f.default)
             for f in dataclasses.fields(ReadOptions) if f.name not in sig.parameters]
    build.__signature__ = sig.replace(  # type: ignore[attr-defined]
        parameters=[p for p in given if p not in tail] + added + tail)
    return build


def given_or_loaded(value: Any, kind: type, load: Callable[[Any], Any], *, label: str, what: str,
                    path: str = "file path") -> tuple[Any, str]:
    """An input a job takes in memory or as a file (a gravity model, a calibration, a layout).

    Parameters
    ----------
    value : object, str or Path
        An instance of ``kind`` (used as is) or a path (read with ``load``).
    kind : type
        The in-memory class (``GravityModel`` ...).
    load : callable
        Reads a path into a ``kind`` (raises SenscalError with the fix when it cannot).
    label : str
        How the result names an input given in memory (``"<model>"``).
    what : str
        How the error names the input (``"the shaft model"``).
    path : str
        How the error names the file it may be (``"MODEL.json path"``).

    Returns
    -------
    (object, str)
        The input and how the result names it: the path as given, or ``label``.
    """
    if isinstance(value, kind):
        return value, label
    if isinstance(value, (str, Path)):
        return load(value), str(value)
    raise InputError(f"{what} must be a {path} or a {kind.__name__}, got {type(value).__name__}")


def document_fields(obj: Any, *names: str) -> dict[str, Any]:
    """JSON of the chosen dataclass fields of ``obj`` (helper for ``to_dict`` overrides)."""
    have = {f.name for f in dataclasses.fields(obj)}
    return {n: to_jsonable(getattr(obj, n)) for n in names if n in have}


def source_name(source: Any) -> str:
    """How a job's result names its input: the path, or the Recording's ``source`` (``"<recording>"``)."""
    if isinstance(source, (str, Path)):
        return str(source)
    return str(getattr(source, "source", None) or "<recording>")


def _split_names(names: str | Sequence[str]) -> tuple[str, ...]:
    """Column names from ``"a, b"`` or a sequence (blanks dropped); none at all is an error."""
    listed = tuple(n.strip() for n in (names.split(",") if isinstance(names, str) else names) if n and n.strip())
    if not listed:
        raise InputError(f"--names expects comma-separated column names, got {names!r}")
    return listed


def read_source(source: Any, *, time_column: str = "t", fs: float | None = None,
                names: str | Sequence[str] | None = None, channels: Sequence[str] | None = None,
                allow_nan: bool = False, time_unit: str | None = None, skip_rows: int | None = None,
                time_required: bool = True, start: float | None = None, stop: float | None = None,
                job: str | None = None):
    """The :class:`~senscal.io.Recording` a job works on.

    Parameters
    ----------
    source : str, Path or Recording
        A recording file (read with the reading options below) or a
        Recording already in memory (used as is; only ``channels`` applies).
    time_column, fs, names, allow_nan, time_unit, skip_rows, time_required
        As :func:`senscal.io.read_recording`; ``names`` may be a
        comma-separated string (as the command line gives it).
    channels : sequence of str, optional
        Keep only these channels (unknown names raise, listing those that exist).
    start, stop : float, optional
        Seconds from the first sample: the window kept (also of a Recording given in memory).
    job : str, optional
        The job reading it: selects the time-base checks of a file (a Recording in memory is used as is).

    Raises
    ------
    SenscalError
        Unreadable file, unknown channel, bad time stamps ... (one line, with the fix).
    """
    from senscal.io import Recording, read_recording

    if isinstance(source, Recording):
        return (source.select(list(channels)) if channels else source).window(start, stop)
    if not isinstance(source, (str, Path)):
        raise InputError(f"a job reads a recording file or a senscal.io.Recording, got {type(source).__name__}")
    if isinstance(names, str) or names:
        names = _split_names(names)
    return read_recording(source, time_column=time_column, fs=fs, names=list(names) if names else None,
                          channels=list(channels) if channels else None, allow_nan=allow_nan,
                          time_unit=time_unit, skip_rows=skip_rows, time_required=time_required,
                          start=start, stop=stop, job=job)
