"""Fuzz harness: a corpus of valid inputs, a seeded byte mutator, and the rules a run must obey.

A *case* is one command line whose input file (a recording of each format or
a side file of each kind) has been mutated.  Whatever the bytes, the command
must end in one of: success (exit 0), a clean error (exit 2 or 3 with exactly
one ``senscal: ...`` line on stderr besides ``warning:`` lines), never a
traceback, never the safety net's "internal error" (exit 1: a bug that the
net caught), never a hang, and never a modified input file.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import signal
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

# Mutated numbers and tokens an adversarial user (or a broken exporter) produces.
_TOKENS = [b"nan", b"inf", b"-inf", b"1e308", b"-1e308", b"1e-320", b"-0", b"", b"abc", b"1e999", b"0", b"-1",
           b"9" * 400, b"[/bold]", b"\xff\xfe", b"\x00", b"null", b"true", b"[]", b"{}", b'"x"', b"1,2", b";",
           b"\t", b"\r\n", b"t", b"ch1 [mV]"]


def mutate(data: bytes, rng: np.random.Generator) -> bytes:
    """One to three random edits of ``data`` (bit flips, cuts, insertions, token swaps, deep nesting)."""
    out = bytearray(data)
    for _ in range(int(rng.integers(1, 4))):
        n = len(out)
        # Mostly edits that keep a text file text, so cases get past the parser into the commands.
        op = int(rng.choice(9, p=[0.10, 0.10, 0.10, 0.05, 0.10, 0.20, 0.15, 0.05, 0.15]))
        if n == 0:
            out += bytes(rng.integers(0, 256, 8, dtype=np.uint8))
            continue
        i = int(rng.integers(0, n))
        if op == 0:  # flip bits
            for j in rng.integers(0, n, int(rng.integers(1, 9))):
                out[int(j)] ^= 1 << int(rng.integers(0, 8))
        elif op == 1:  # truncate
            del out[i:]
        elif op == 2:  # delete a span
            del out[i:i + int(rng.integers(1, 64))]
        elif op == 3:  # insert random bytes
            out[i:i] = bytes(rng.integers(0, 256, int(rng.integers(1, 16)), dtype=np.uint8))
        elif op == 4:  # duplicate a span
            out[i:i] = out[i:i + int(rng.integers(1, 256))]
        elif op in (5, 6):  # replace a token (a run of non-separators) with a hostile one
            seps = b",;\t\n\r :[]{}\""
            j = i
            while j < n and out[j] not in seps:
                j += 1
            k = i
            while k > 0 and out[k - 1] not in seps:
                k -= 1
            out[k:j] = _TOKENS[int(rng.integers(0, len(_TOKENS)))]
        elif op == 7:  # deep nesting (JSON/YAML parsers recurse)
            depth = int(rng.integers(1000, 100000))
            out[i:i] = b"[" * depth
        else:  # overwrite a whole line with another line of the file
            lines = bytes(out).split(b"\n")
            if len(lines) > 2:
                a, b = (int(x) for x in rng.integers(0, len(lines), 2))
                lines[a] = lines[b]
                out = bytearray(b"\n".join(lines))
    return bytes(out)


@dataclass
class Target:
    """A command line with one file to mutate (``{f}``) and an output folder (``{o}``)."""

    command: str
    argv: Sequence[str]
    seed_file: Path
    suffix: str = ""

    def args(self, f: Path, o: Path) -> list[str]:
        return [a.replace("{f}", str(f)).replace("{o}", str(o)) for a in self.argv]


@dataclass
class Tally:
    """Outcomes per command."""

    counts: dict[str, Counter] = field(default_factory=dict)
    failures: list[str] = field(default_factory=list)

    def add(self, command: str, kind: str, detail: str | None = None) -> None:
        self.counts.setdefault(command, Counter())[kind] += 1
        if detail is not None:
            self.failures.append(f"[{command}] {kind}: {detail}")

    def table(self) -> str:
        kinds = ["cases", "ok", "clean", "traceback", "internal", "multiline", "hang", "modified"]
        rows = ["| command | " + " | ".join(kinds) + " |", "|" + "---|" * (len(kinds) + 1)]
        total: Counter = Counter()
        for cmd in sorted(self.counts):
            c = self.counts[cmd]
            c["cases"] = sum(v for k, v in c.items() if k != "cases")
            total.update(c)
            rows.append(f"| {cmd} | " + " | ".join(str(c.get(k, 0)) for k in kinds) + " |")
        rows.append("| **all** | " + " | ".join(str(total.get(k, 0)) for k in kinds) + " |")
        return "\n".join(rows)


class FuzzTimeout(BaseException):
    """Raised by the alarm in a hung case (a BaseException, so the CLI's safety net does not swallow it)."""


def _digest(paths: Sequence[Path]) -> dict[str, str]:
    out = {}
    for p in paths:
        if p.is_file():
            out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def classify(code: int, err: str) -> tuple[str, str | None]:
    """``(kind, detail)`` of one run; detail is None for acceptable outcomes."""
    if "Traceback (most recent call last)" in err:
        return "traceback", err.strip().splitlines()[-1][:300]
    if code == 1 or "internal error" in err:
        return "internal", err.strip()[:300]
    if code not in (0, 2, 3):
        return "internal", f"exit code {code}: {err.strip()[:300]}"
    if code == 0:
        return "ok", None
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("warning:")]
    if len(lines) != 1 or not lines[0].startswith("senscal: "):
        return "multiline", " | ".join(lines)[:300]
    return "clean", None


def run_case(run: Callable[..., object], args: Sequence[str], inputs: Sequence[Path],
             timeout_s: float) -> tuple[str, str | None]:
    """Run one command line in-process under an alarm and classify it (also checks inputs unchanged)."""
    before = _digest(inputs)

    def _alarm(signum, frame):
        raise FuzzTimeout()

    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout_s)
    try:
        res = run(*args)
        kind, detail = classify(res.code, res.err)  # type: ignore[attr-defined]
    except FuzzTimeout:
        kind, detail = "hang", f"no answer within {timeout_s:g} s: {' '.join(map(str, args))[:200]}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    if _digest(inputs) != before:
        kind, detail = "modified", f"an input changed: {' '.join(map(str, args))[:200]}"
    if detail is not None:
        detail = f"{detail}  <- senscal {' '.join(map(str, args))[:300]}"
    return kind, detail


def quiet_main(args: Sequence[str]) -> tuple[int, str, str]:
    """Run ``senscal`` in-process with captured output (for building the corpus)."""
    from senscal.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            main([str(a) for a in args])
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return code, out.getvalue(), err.getvalue()


def _sim(args: Sequence[str]) -> None:
    code, _, err = quiet_main(args)
    if code != 0:
        raise RuntimeError(f"corpus: senscal {' '.join(map(str, args))} failed: {err}")


def build_corpus(d: Path) -> list[Target]:
    """Valid seed inputs of every format and side-file kind, each with the command that reads it."""
    from senscal.io import Recording, write_recording

    d.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(1)
    t = np.arange(400) / 400.0
    rec = Recording(channels={"x": 1.5 * np.sin(2 * np.pi * 10 * t + 0.3) + rng.normal(0, 0.01, t.size),
                              "y": 0.5 * np.cos(2 * np.pi * 10 * t) + rng.normal(0, 0.01, t.size)},
                    t=t, units={"x": "V", "y": "V"})
    targets: list[Target] = []
    for ext in (".csv", ".parquet", ".h5", ".tdms", ".npz"):
        p = write_recording(rec, d / f"sine{ext}", units_in_header=True)
        targets.append(Target(f"fit{ext}", ["fit", "{f}", "--freq", "10", "--json"], p, ext))
    rec_fs = Recording(channels={"x": rec["x"]}, fs=400.0)
    for ext in (".parquet", ".npz"):
        p = write_recording(rec_fs, d / f"sine_fs{ext}")
        targets.append(Target(f"fit-fs{ext}", ["fit", "{f}", "--json"], p, ext))
    _sim(["simulate", "hydraulic", "--out", d / "hy", "--seed", "1", "--freqs", "2,4"])
    hy = sorted((d / "hy").glob("hydraulic_*.csv"))
    targets.append(Target("velocity", ["velocity", "{f}", str(hy[1]), "--position", "position", "--velocity",
                                       "velocity", "--json"], hy[0], ".csv"))
    _sim(["simulate", "shaker", "--out", d / "sh", "--seed", "1", "--freqs", "80,160"])
    sh = sorted((d / "sh").glob("shaker_*.csv"))
    targets.append(Target("response", ["response", "{f}", str(sh[1]), "--output", "dut", "--reference", "reference",
                                       "--reference-sensitivity", "0.0102", "--json"], sh[0], ".csv"))
    _sim(["simulate", "shaft", "--out", d / "shaft", "--seed", "1", "--fs", "200", "--cal-duration", "6",
          "--test-duration", "3"])
    targets.append(Target("shaft calibrate", ["shaft", "calibrate", "{f}", "--angle", "angle", "--accel", "accel",
                                              "--json"], d / "shaft" / "shaft_cal.csv", ".csv"))
    _sim(["shaft", "calibrate", d / "shaft" / "shaft_cal.csv", "--angle", "angle", "--accel", "accel", "--out",
          d / "shaft" / "model.json"])
    targets.append(Target("shaft compensate --model", ["shaft", "compensate", str(d / "shaft" / "shaft_test.csv"),
                                                       "--model", "{f}", "--angle", "angle", "--accel", "accel",
                                                       "--radius", "0.1", "--json"],
                          d / "shaft" / "model.json", ".json"))
    _sim(["simulate", "magnetometer", "--out", d / "mag", "--seed", "1", "--n", "150"])
    mag = d / "mag" / "magnetometer.csv"
    targets.append(Target("triaxial calibrate", ["triaxial", "calibrate", "{f}", "--channels", "x,y,z", "--json"],
                          mag, ".csv"))
    _sim(["triaxial", "calibrate", mag, "--channels", "x,y,z", "--out", d / "mag" / "params.json"])
    targets.append(Target("triaxial apply --params", ["triaxial", "apply", str(mag), "--params", "{f}",
                                                      "--channels", "x,y,z", "--out", "{o}/applied.csv"],
                          d / "mag" / "params.json", ".json"))
    _sim(["simulate", "gfimu", "--out", d / "gf", "--seed", "1", "--duration", "0.5", "--fs", "200"])
    targets.append(Target("gfimu", ["gfimu", "{f}", "--layout", str(d / "gf" / "layout.csv"), "--method",
                                    "integration", "--json"], d / "gf" / "gfimu.csv", ".csv"))
    targets.append(Target("gfimu --layout", ["gfimu", str(d / "gf" / "gfimu.csv"), "--layout", "{f}", "--method",
                                             "integration", "--json"], d / "gf" / "layout.csv", ".csv"))
    _sim(["simulate", "drift", "--out", d / "dr", "--seed", "1", "--samples", "300"])
    drift_csv = d / "dr" / "drift.csv"
    header = drift_csv.read_text().splitlines()[0].split(",")
    chans = [c for c in header if c not in ("t", "temperature")]
    targets.append(Target("drift", ["drift", "{f}", "--preset", "redundant", "--trusted", chans[0], "--channels",
                                    ",".join(chans[:2]), "--no-compare", "--json"], drift_csv, ".csv"))
    yml = d / "dr" / "model.yaml"
    yml.write_text(f"channels: [{chans[0]}, {chans[1]}]\ntrusted: [{chans[0]}]\n"
                   "signal: {kind: random_walk}\nnoise_std: {" + f"{chans[0]}: 0.05" + "}\n"
                   f"biases:\n  - {{channel: {chans[1]}}}\n")
    targets.append(Target("drift --model", ["drift", str(drift_csv), "--preset", "model", "--model", "{f}",
                                            "--no-compare", "--json"], yml, ".yaml"))
    _sim(["simulate", "registry", "--out", d / "reg", "--seed", "1"])
    targets.append(Target("registry import", ["registry", "import", "{f}", "--db", "{o}/reg.sqlite", "--json"],
                          d / "reg" / "history.json", ".json"))
    import h5py

    arr = np.stack([a * np.sin(2 * np.pi * 10 * t) for a in (1.0, 2.0, 3.0)])
    with h5py.File(d / "array.h5", "w") as fh:
        fh.create_dataset("y", data=arr).attrs["fs"] = 400.0
        fh.create_dataset("t", data=t)
    targets.append(Target("fit-array", ["fit-array", "{f}", "--dataset", "y", "--time-dataset", "t", "--out",
                                        "{o}/fa.csv", "--json"], d / "array.h5", ".h5"))
    return targets


def check_seeds(targets: Sequence[Target], o: Path) -> list[str]:
    """The unmutated seeds must run cleanly (else the fuzz would only exercise the first error)."""
    bad = []
    o.mkdir(parents=True, exist_ok=True)  # outputs go into an existing folder (a missing one is refused)
    for tg in targets:
        code, _, err = quiet_main(tg.args(tg.seed_file, o))
        if code != 0:
            bad.append(f"{tg.command}: exit {code}: {err.strip()[:200]}")
    return bad


def fuzz_target(run: Callable[..., object], tg: Target, n_cases: int, seed: int, work: Path,
                tally: Tally, timeout_s: float) -> None:
    """``n_cases`` mutations of one target's seed file, each run and classified into ``tally``."""
    rng = np.random.default_rng(seed)
    data = tg.seed_file.read_bytes()
    other_inputs = [Path(a) for a in tg.argv if a.startswith(os.sep) and Path(a).is_file()]
    for i in range(n_cases):
        f = work / f"case{i}{tg.suffix}"
        f.write_bytes(mutate(data, rng))
        o = work / f"out{i}"
        o.mkdir(exist_ok=True)
        kind, detail = run_case(run, tg.args(f, o), [f, *other_inputs], timeout_s)
        tally.add(tg.command, kind, detail)
        with contextlib.suppress(OSError):
            f.unlink()


TALLY = Tally()

# CI: a fixed budget of a few minutes on 2 cores; SENSCAL_FUZZ=long for the nightly run.
LONG = os.environ.get("SENSCAL_FUZZ", "").lower() == "long"
CASES_PER_TARGET = 300 if LONG else 40
CASE_TIMEOUT_S = 60.0 if LONG else 30.0


def dump_summary(tally: Tally, path: str | None) -> None:
    if path:
        Path(path).write_text(json.dumps({k: dict(v) for k, v in tally.counts.items()}, indent=1))
