"""What every job result shares: the JSON document, the registry quantities, a table."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, ClassVar, Sequence

from senscal._result import ResultMixin, to_jsonable
from senscal.errors import InputError
from senscal.quantity import Quantity

__all__ = ["JobResult", "Quantity", "read_source", "source_name", "document_fields"]


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


def document_fields(obj: Any, *names: str) -> dict[str, Any]:
    """JSON of the chosen dataclass fields of ``obj`` (helper for ``to_dict`` overrides)."""
    have = {f.name for f in dataclasses.fields(obj)}
    return {n: to_jsonable(getattr(obj, n)) for n in names if n in have}


def source_name(source: Any) -> str:
    """How a job's result names its input: the path, or the Recording's ``source`` (``"<recording>"``)."""
    if isinstance(source, (str, Path)):
        return str(source)
    return str(getattr(source, "source", None) or "<recording>")


def read_source(source: Any, *, time_column: str = "t", fs: float | None = None,
                names: str | Sequence[str] | None = None, channels: Sequence[str] | None = None,
                allow_nan: bool = False, time_unit: str | None = None, skip_rows: int | None = None,
                time_required: bool = True):
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

    Raises
    ------
    SenscalError
        Unreadable file, unknown channel, bad time stamps ... (one line, with the fix).
    """
    from senscal.io import Recording, read_recording

    if isinstance(source, Recording):
        return source.select(list(channels)) if channels else source
    if not isinstance(source, (str, Path)):
        raise InputError(f"a job reads a recording file or a senscal.io.Recording, got {type(source).__name__}")
    if isinstance(names, str):
        names = [s.strip() for s in names.split(",") if s.strip()]
        if not names:
            raise InputError("--names expects comma-separated column names")
    return read_recording(source, time_column=time_column, fs=fs, names=list(names) if names else None,
                          channels=list(channels) if channels else None, allow_nan=allow_nan,
                          time_unit=time_unit, skip_rows=skip_rows, time_required=time_required)
