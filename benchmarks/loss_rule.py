"""The loss flag's evidence on the dev set (issue 13): how well each candidate signal separates bad
frames (mean tip error over 8 px) from good ones (under 3 px), and a leave-one-sequence-out check
of the support rule (:mod:`jaxhand.track._support`).

Reads ``benchmarks/results/loss_signals.json`` (``benchmarks/loss_signals.py``). Per signal: the
area under the ROC curve (bad against good), and the share of bad frames above the threshold that
flags 5 % of the good ones. Then the rule "flagged before, or weakest finger support < t, or an
unexplained blob >= a px": t and a chosen on four sequences (the most bad frames flagged with at
most 4 % of the good ones), scored on the fifth.

    .venv/bin/python benchmarks/loss_rule.py [--json loss_signals_robust_limits.json]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import RESULTS, format_table  # noqa: E402

#: Candidate signals, oriented so that a high value speaks against the frame.
SIGNALS = {
    "hypothesis spread (px)": lambda r: r["spread_px"],
    "residual RMS (px)": lambda r: r["rms_px"],
    "jump prediction-solve (px)": lambda r: r["jump_px"],
    "1 - valid share": lambda r: 1 - r["valid_share"],
    "1 - silhouette term merit": lambda r: 1 - r["term_merit"],
    "1 - confidence (before)": lambda r: 1 - r["confidence"],
    "1 - weakest finger support": lambda r: 1 - (r["support"] if r["support"] == r["support"] else 1.0),
    "unexplained blob, 1 px margin": lambda r: r["unexplained_m1"],
    "unexplained blob, 2 px margin": lambda r: r["unexplained_m2"],
    "unexplained blob, 3 px margin": lambda r: r["unexplained_m3"],
}
SUPPORT_T = np.round(np.arange(0.80, 0.951, 0.005), 3)
BLOB_A = (2, 4, 8, 16, 32, 64, 10 ** 9)


def auc(x, bad, good) -> float:
    a, b = x[bad], x[good]
    return float(np.mean(a[:, None] > b[None]) + 0.5 * np.mean(a[:, None] == b[None]))


def rates(flag, bad, good, sel) -> tuple[float, float]:
    """(share of the bad frames flagged, share of the good ones) within ``sel``."""
    return (float(flag[bad & sel].mean()) if (bad & sel).any() else float("nan"),
            float(flag[good & sel].mean()) if (good & sel).any() else float("nan"))


def fit(flags: dict, bad, good, train, cap: float = 0.04):
    """The rule's (t, a) with the most bad training frames flagged, at most ``cap`` of the good."""
    def key(p):
        rb, rg = rates(flags[p], bad, good, train)
        return (rg <= cap, rb, -rg)
    return max(flags, key=key)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--json", default="loss_signals.json", help="loss_signals.py's file under benchmarks/results/")
    args = p.parse_args(argv)
    rows = json.loads((RESULTS / args.json).read_text())["frames"]
    seq = np.array([r["sequence"] for r in rows])
    err = np.array([r["tip_error_px"] for r in rows])
    bad, good = err > 8.0, err < 3.0
    before = np.array([r["lost"] or r["confidence"] < 0.5 for r in rows])
    names = [s for s in dict.fromkeys(seq) if (bad & (seq == s)).any()]
    table = []
    for label, f in SIGNALS.items():
        x = np.array([f(r) for r in rows], float)
        t = np.quantile(x[good], 0.95)
        table.append([label, f"{auc(x, bad, good):.3f}", f"{np.mean(x[bad] > t):.2f}"]
                     + [f"{np.mean(x[bad & (seq == s)] > t):.2f}" for s in names])
    print(format_table(table, ["signal", "AUC", "bad flagged at 5% good"] + names))
    support = np.array([r["support"] if r["support"] == r["support"] else 1.0 for r in rows])
    blob = np.array([r["unexplained_m1"] for r in rows], float)
    flags = {(t, a): before | (support < t) | (blob >= a) for t in SUPPORT_T for a in BLOB_A}
    loo, table = np.zeros(len(rows), bool), []
    for s in dict.fromkeys(seq):
        test = seq == s
        t, a = fit(flags, bad, good, ~test)
        loo[test] = flags[(t, a)][test]
        rb, rg = rates(flags[(t, a)], bad, good, test)
        best = rates(flags[(t, a)], bad, good, ~test)
        tied = [b for b in BLOB_A if rates(flags[(t, b)], bad, good, ~test) == best]   # same on the training set
        table.append([s, f"{t:.3f}", "-".join(str(b) if b < 10 ** 9 else "off" for b in (tied[0], tied[-1])),
                      f"{rb:.2f}", f"{rg:.3f}"])
    print(format_table(table, ["held out", "support t", "blob a (px), tied", "bad flagged", "good flagged"]))
    everything = np.ones(len(rows), bool)
    chosen = before | (support < 0.88) | (blob > 8)
    for label, flag in (("held out", loo), ("before", before), ("the preset's levels (t 0.88, a > 8 px)", chosen)):
        rb, rg = rates(flag, bad, good, everything)
        print(f"pooled, {label}: bad {rb:.2f} good {rg:.3f}")

if __name__ == "__main__":
    main()
