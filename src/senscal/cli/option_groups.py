"""Option blocks many commands share, added to a command's signature in one line.

A calibration command that reads a recording and can record its result in the registry lists the same
eight reading options and six registry options; copying them into every signature let them drift apart.
:func:`with_options` appends a block's parameters to the command's signature (typer reads the signature),
and the command receives them in its ``**opts``::

    @triaxial_app.command("calibrate")
    @with_options(READ, REGISTRY)
    def calibrate_cmd(file: ..., channels: ..., json_out: JsonOpt = False, **opts) -> None:
        result = triaxial_calibrate(file, _calibrate_options(**locals(), **opts))
        save_registered(result, opts, job="triaxial", method=..., input_files=[file])
"""

from __future__ import annotations

import functools
import inspect
from typing import Any, Callable, Mapping

from senscal.cli.common import FsOpt, NamesOpt, SkipRowsOpt, StartOpt, StopOpt, TimeColumnOpt, TimeUnitOpt
from senscal.cli.registry_opts import CreateSensorOpt, DateOpt, DbOpt, OperatorOpt, SaveOpt, SensorOpt

__all__ = ["READ", "REGISTRY", "with_options", "save_registered", "command_params"]

#: How a recording is read: ``{parameter: (annotation, default)}``.
READ: Mapping[str, tuple[Any, Any]] = {
    "time_column": (TimeColumnOpt, "t"), "fs": (FsOpt, None), "names": (NamesOpt, None),
    "skip_rows": (SkipRowsOpt, None), "time_unit": (TimeUnitOpt, None), "start": (StartOpt, None),
    "stop": (StopOpt, None)}

#: ``--save --sensor --db --create-sensor --date --operator`` (:mod:`senscal.cli.registry_opts`).
REGISTRY: Mapping[str, tuple[Any, Any]] = {
    "save": (SaveOpt, False), "sensor": (SensorOpt, None), "db": (DbOpt, None),
    "create_sensor": (CreateSensorOpt, None), "date": (DateOpt, None), "operator": (OperatorOpt, None)}


def with_options(*blocks: Mapping[str, tuple[Any, Any]]) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Append option blocks to a command's signature; the command takes them as ``**opts``.

    The command's own parameters come first (in its order), then each block's; a name the command already
    declares is left to the command.
    """

    def deco(fn: Callable[..., Any]) -> Callable[..., Any]:
        sig = inspect.signature(fn, eval_str=True)
        own = [p for p in sig.parameters.values() if p.kind is not p.VAR_KEYWORD]
        names = {p.name for p in own}
        added = [inspect.Parameter(n, inspect.Parameter.KEYWORD_ONLY, default=d, annotation=a)
                 for block in blocks for n, (a, d) in block.items() if n not in names]

        @functools.wraps(fn)
        def command(*args: Any, **kw: Any) -> Any:
            return fn(*args, **kw)

        command.__signature__ = sig.replace(parameters=own + added)  # type: ignore[attr-defined]
        command.__annotations__ = {p.name: p.annotation for p in own + added}
        return command

    return deco


def command_params(local: Mapping[str, Any], opts: Mapping[str, Any]) -> dict[str, Any]:
    """A command's own parameters (``locals()`` without ``opts``) and its block options, in one mapping."""
    return {**{k: v for k, v in local.items() if k != "opts"}, **opts}


def save_registered(result: Any, opts: Mapping[str, Any], **kw: Any) -> None:
    """:func:`senscal.cli.registry_opts.save_if_requested` with the :data:`REGISTRY` block's values."""
    from senscal.cli.registry_opts import save_if_requested

    save_if_requested(result, **{n: opts.get(n, d) for n, (_, d) in REGISTRY.items()}, **kw)
