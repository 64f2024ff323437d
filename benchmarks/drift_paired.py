"""Paired before/after check of the drift job's results on the coverage scenarios (issue 30).

    PYTHONPATH=<old src> python benchmarks/drift_paired.py capture before.json [--seeds 20] [--only white,known]
    PYTHONPATH=<new src> python benchmarks/drift_paired.py capture after.json  [--seeds 20] [--only white,known]
    python benchmarks/drift_paired.py compare before.json after.json

``capture`` runs every scenario of :mod:`senscal.validation.drift` (the
same seeds each time) and stores, per fit, the final and mid-record bias
with its u, every noise level with its u, the log-likelihood, the selected
model and the warning names.  ``compare`` prints, per scenario, the largest
change of each in units of the *before* u (``|b_after - b_before| / u``),
the largest relative change of u, of the likelihood, and how many fits
changed their selected model or warnings.  A speed change that keeps the
arithmetic shows zeros everywhere; one that moves an optimiser's path shows
how far, in the unit a user reads (snapshot the old source tree, e.g.
``cp -r src /tmp/before_src``, before editing).
"""

from __future__ import annotations

import json
import time

import numpy as np


def capture(out_path: str, seeds: int, only: list[str] | None) -> None:
    import senscal.validation.drift as V

    out = []
    orig = V.correct_drift
    scen = [None]

    def wrap(*a, **k):
        r = orig(*a, **k)
        mid = r.bias.shape[1] // 2
        out.append(dict(scen=scen[0], bias_fin=r.bias[:, -1].tolist(), u_fin=r.bias_std[:, -1].tolist(),
                        bias_mid=r.bias[:, mid].tolist(), u_mid=r.bias_std[:, mid].tolist(),
                        noise={p.name: [p.value, p.std] for p in r.noise}, loglik=r.loglik,
                        selected=getattr(r, "selected", None),
                        warnings=sorted(w.split(":")[0] for w in r.warnings)))
        return r

    V.correct_drift = wrap
    try:
        for name in only or list(V.SCENARIOS):
            scen[0] = name
            t0 = time.process_time()
            V.SCENARIOS[name](seeds, 1000)
            print(f"{name}: {time.process_time() - t0:.1f} s CPU", flush=True)
            with open(out_path, "w") as fh:
                json.dump(out, fh)
    finally:
        V.correct_drift = orig


def compare(a_path: str, b_path: str) -> None:
    from _paired import load_pairs

    by = load_pairs(a_path, b_path, "scenarios")
    print(f"{'scenario':22} {'n':>3} {'fin |db|/u':>10} {'mid |db|/u':>10} {'|du|/u':>8} {'lvl |dv|/u':>10} "
          f"{'|dlnL|':>8} {'sel':>4} {'warn':>4} {'identical':>9}")
    for s, pairs in by.items():
        zf, zm, zu, zl, dll, sel, warn, same = [], [], [], [], [], 0, 0, 0
        for a, b in pairs:
            ua = np.array(a["u_fin"])
            zf.append(np.max(np.abs(np.array(a["bias_fin"]) - b["bias_fin"]) / ua))
            zm.append(np.max(np.abs(np.array(a["bias_mid"]) - b["bias_mid"]) / np.array(a["u_mid"])))
            zu.append(np.max(np.abs(ua - np.array(b["u_fin"])) / ua))
            for k, (v, u) in a["noise"].items():
                if k in b["noise"] and u:
                    zl.append(abs(v - b["noise"][k][0]) / u)
            dll.append(abs(b["loglik"] - a["loglik"]))
            sel += a["selected"] != b["selected"]
            warn += a["warnings"] != b["warnings"]
            same += a == b
        print(f"{s:22} {len(pairs):>3} {max(zf):10.4f} {max(zm):10.4f} {max(zu):8.4f} "
              f"{max(zl) if zl else 0.0:10.4f} {max(dll):8.4f} {sel:>4} {warn:>4} {same:>9}")


def main() -> None:
    from _paired import paired_main

    paired_main(__doc__, capture, compare, seeds=20, only_help="comma-separated scenario names")


if __name__ == "__main__":
    main()
