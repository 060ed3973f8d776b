#!/usr/bin/env python3
"""Turns the raw lines of `scripts/bench lcm` into its Markdown table, and keeps the list of
every full run made with this method.

The method, fixed before the runs it reports (and printed under the table by `method()`):

- Latency figures are the pooled percentiles (p50, p99) of every round trip of every round:
  each ping run prints all its round trips, and the runs of one program are pooled.
- Throughput is all messages of all rounds over the time they took.
- Each ratio (Rust / C, and the A/A control C again / C) has a 95 % bootstrap interval: the
  rounds are resampled with replacement (a round's C, Rust and control runs kept together),
  RESAMPLES times, with a fixed seed, and the figure recomputed on each resample.
- Verdict against the bar (Rust within 5 % of C): "holds" when the whole interval is within the
  bar, "fails" when the whole interval is outside it, "not shown" otherwise (the interval
  straddles the bar: this run cannot tell). A message Rust lost fails the figure; one C lost
  leaves it not shown.

usage: bench-lcm-table.py RAW [--history BENCHMARKS.md] [--record DATE COMMIT]
"""
import bisect
import random
import re
import sys

BAR = 0.05
RESAMPLES = 1000
SIZES = {"100": "100 B", "10000": "10 kB", "1000000": "1 MB"}
FIGURES = (
    ("latency", 50.0, "round trip p50 (pooled)", "µs", False),
    ("latency", 99.0, "round trip p99 (pooled)", "µs", False),
    ("throughput", None, "one-way message rate", "msg/s", True),
)


def method(resamples=RESAMPLES):
    return (
        "Method (fixed before these runs, by `scripts/bench-lcm-table.py`): latency figures are "
        "the pooled percentiles of every round trip of every round; throughput is all messages of "
        "all rounds over the time they took. Each ratio's 95 % interval resamples the rounds "
        f"({resamples} resamples, fixed seed; a round's C, Rust and control runs kept together). "
        "Verdict: *holds* when the whole interval is within the bar (Rust / C ≤ 1.05 for times, "
        "≥ 0.95 for rates), *fails* when the whole interval is outside it, *not shown* when it "
        "straddles the bar; a message Rust lost fails the figure, one C lost leaves it not shown."
    )


def load(path):
    rows, extra = [], {}
    for line in open(path):
        f = dict(kv.split("=", 1) for kv in line.split() if "=" in kv)
        if f.get("mode") == "instructions":
            extra[f["who"]] = int(f["per_msg"])
        elif "round" in f:
            if "rtt_ns" in f:
                f["rtt"] = [int(v) for v in f["rtt_ns"].split(",") if v]
            rows.append(f)
    return rows, extra


def pooled_percentile(runs, p):
    """The p-th percentile (nearest rank) of the union of the runs' sorted samples, without
    merging them: a binary search on the value over the counts at or below it."""
    total = sum(len(r) for r in runs)
    if total == 0:
        return float("nan")
    k = max(1, -(-int(round(p * total)) // 100))  # the rank, 1-based
    lo = min(r[0] for r in runs if r)
    hi = max(r[-1] for r in runs if r)
    while lo < hi:
        mid = (lo + hi) // 2
        if sum(bisect.bisect_right(r, mid) for r in runs) >= k:
            hi = mid
        else:
            lo = mid + 1
    return float(lo)


def figure(runs, mode, p):
    if mode == "throughput":
        msgs = sum(float(r["count"]) - float(r["lost"]) for r in runs)
        secs = sum((float(r["count"]) - float(r["lost"])) / float(r["msgs_per_s"]) for r in runs)
        return msgs / secs if secs > 0 else 0.0
    return pooled_percentile([r["rtt"] for r in runs], p) / 1e3


def verdict(lo, hi, higher, lost_c, lost_r):
    if lost_r:
        return "fails"
    if lost_c:
        return "not shown"
    if higher:
        return "holds" if lo >= 1 - BAR else ("fails" if hi < 1 - BAR else "not shown")
    return "holds" if hi <= 1 + BAR else ("fails" if lo > 1 + BAR else "not shown")


def table(rows, extra):
    rng = random.Random(1)
    out = [
        "| size | figure | C (liblcm) | Rust (lcm crate) | Rust / C | 95 % interval | bar "
        "| C again / C (A/A control) | control's 95 % interval | lost C / Rust | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    counts = {"holds": 0, "not shown": 0, "fails": 0}
    unresolved = []
    n_rounds = 0
    for size, sz in SIZES.items():
        for mode, p, label, unit, higher in FIGURES:
            by_round = {}
            for r in rows:
                if r["mode"] == mode and r["size"] == size:
                    by_round.setdefault(r["round"], {})[r["who"]] = r
            rounds = [v for v in by_round.values() if {"c", "cc", "rust"} <= v.keys()]
            n_rounds = max(n_rounds, len(rounds))
            if not rounds:
                continue

            def three(sample):
                return tuple(figure([v[w] for v in sample], mode, p) for w in ("c", "rust", "cc"))

            c, r, cc = three(rounds)
            boot, ctrl = [], []
            for _ in range(RESAMPLES):
                bc, br, bcc = three([rng.choice(rounds) for _ in rounds])
                boot.append(br / bc)
                ctrl.append(bcc / bc)
            boot.sort()
            ctrl.sort()
            lo, hi = boot[int(0.025 * RESAMPLES)], boot[int(0.975 * RESAMPLES) - 1]
            clo, chi = ctrl[int(0.025 * RESAMPLES)], ctrl[int(0.975 * RESAMPLES) - 1]
            lost_c = sum(int(v["c"]["lost"]) for v in rounds)
            lost_r = sum(int(v["rust"]["lost"]) for v in rounds)
            v = verdict(lo, hi, higher, lost_c, lost_r)
            counts[v] += 1
            if v != "holds":
                unresolved.append(f"{sz} {label.split(' (')[0]} ({v})")
            bar = "≥ 0.95" if higher else "≤ 1.05"
            fmt = (lambda x: f"{x:.1f}") if unit == "µs" else (lambda x: f"{x:.0f}")
            out.append(
                f"| {sz} | {label} | {fmt(c)} {unit} | {fmt(r)} {unit} | {r / c:.3f} "
                f"| {lo:.3f} to {hi:.3f} | {bar} | {cc / c:.3f} | {clo:.3f} to {chi:.3f} "
                f"| {lost_c} / {lost_r} | {v} |"
            )
            if mode == "throughput":
                mb = lambda x: x * int(size) / 1e6  # noqa: E731
                out.append(
                    f"| {sz} | one-way throughput (the rate in MB/s) | {mb(c):.1f} MB/s "
                    f"| {mb(r):.1f} MB/s | {r / c:.3f} | {lo:.3f} to {hi:.3f} | {bar} "
                    f"| {cc / c:.3f} | {clo:.3f} to {chi:.3f} | {lost_c} / {lost_r} | {v} |"
                )
    out.append("")
    shown = "the bar is shown to hold for every figure" if counts["holds"] == 9 else (
        f"the bar is NOT shown to hold for {9 - counts['holds']} of 9 figures: "
        + ", ".join(unresolved)
    )
    out.append(
        f"{counts['holds']} of 9 figures hold, {counts['not shown']} not shown, "
        f"{counts['fails']} fail ({n_rounds} rounds): {shown}."
    )
    if "c" in extra and "rust" in extra:
        lat = [v for v in rows if v["mode"] == "latency" and v["size"] == "100" and v["who"] == "c"]
        p50 = figure(lat, "latency", 50.0) if lat else 0
        d = extra["rust"] - extra["c"]
        out.append("")
        out.append(
            "Library cost in user space (callgrind, publish + dispatch of a 100-byte message on "
            f"memq://): C {extra['c']} instructions per message, Rust {extra['rust']} (the "
            f"wrapper adds {d}, about {d / 2500:.2f} µs at 2.5 instructions/ns, against a "
            f"{p50:.0f} µs round trip)."
        )
    summary = (n_rounds, counts, unresolved)
    return "\n".join(out), summary


RUNS_START, RUNS_END = "<!-- lcm-runs:start -->", "<!-- lcm-runs:end -->"
RUNS_HEAD = [
    "| run | date | commit | rounds | hold | not shown | fail | figures not shown to hold |",
    "|---|---|---|---|---|---|---|---|",
]


def history(path):
    """The rows of the list of full runs in BENCHMARKS.md (written only by this script)."""
    try:
        text = open(path).read()
    except OSError:
        return []
    m = re.search(re.escape(RUNS_START) + "(.*?)" + re.escape(RUNS_END), text, re.S)
    if not m:
        return []
    return [
        line for line in m.group(1).splitlines()
        if line.startswith("| ") and not line.startswith("| run ") and not line.startswith("|---")
    ]


def main(argv):
    raw = argv[1]
    hist_path = argv[argv.index("--history") + 1] if "--history" in argv else None
    record = argv[argv.index("--record") + 1: argv.index("--record") + 3] if "--record" in argv else None
    rows, extra = load(raw)
    text, (n_rounds, counts, unresolved) = table(rows, extra)
    print(text)
    print()
    print(method())
    if hist_path is None:
        return
    runs = history(hist_path)
    if record:
        date, commit = record
        runs.append(
            f"| {len(runs) + 1} | {date} | {commit} | {n_rounds} | {counts['holds']} "
            f"| {counts['not shown']} | {counts['fails']} | {', '.join(unresolved) or 'none'} |"
        )
    print()
    print(
        "Every full run made with this method, the one above last (none left out; "
        "`--table-only` rebuilds the table above without adding a run):"
    )
    print()
    print(RUNS_START)
    print("\n".join(RUNS_HEAD + runs))
    print(RUNS_END)


if __name__ == "__main__":
    main(sys.argv)
