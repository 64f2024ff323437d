"""What every job result shares: the JSON document, the registry quantities, a table."""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

from senscal._result import ResultMixin, to_jsonable
from senscal.quantity import Quantity

__all__ = ["JobResult", "Quantity"]


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
