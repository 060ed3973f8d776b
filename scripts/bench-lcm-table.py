#!/usr/bin/env python3
"""Turns the raw lines of `scripts/bench lcm` into its Markdown table, and keeps the list of
every full run made with this method.

The method (printed under the table by `method()`; method 2, with the counted verdict, from run
3 on):

- Latency figures are the pooled percentiles (p50, p99) of every round trip of every round:
  each ping run prints all its round trips, and the runs of one program are pooled.
- Throughput is all messages of all rounds over the time they took.
- Each ratio (Rust / C, and the A/A control C again / C) has a 95 % bootstrap interval: the
  rounds are resampled with replacement (a round's C, Rust and control runs kept together),
  RESAMPLES times, with a fixed seed, and the figure recomputed on each resample.
- Verdict against the bar (Rust within 5 % of C): "holds" when the whole interval is within the
  bar, "fails" when the whole interval is outside it. A message Rust lost fails the figure.
- Where the interval straddles the bar (the timing cannot tell: the A/A control's own interval
  is about as wide as the bar), or C lost a message, the exact count decides. Both programs
  make the same liblcm calls, so the kernel's and liblcm's work per message is the same; what
  Rust adds is user-space instructions, counted by callgrind per message at that size (publish
  + dispatch on memq://). That count, times the messages of the figure's unit (a round trip
  carries two, a streamed message one), at the speed this machine runs liblcm's own
  instructions (C's memq:// loop: its instructions over its time, the slowest of its timed
  runs; IPNS instructions per nanosecond without them), as a share of C's time for the unit,
  gives the ratio Rust would show with no noise: "holds (counted)" or "fails (counted)" against
  the same bar. Without the counts such a figure stays "not shown".

usage: bench-lcm-table.py RAW [--history BENCHMARKS.md] [--record DATE COMMIT]
"""
import bisect
import random
import re
import sys

BAR = 0.05
RESAMPLES = 1000
# Instructions per nanosecond for the counted verdict when the C loop was not timed: a floor
# (this machine runs liblcm at about 5), so that the time Rust adds is overstated.
IPNS = 1.0
# Messages through the library (a publish and a dispatch each) per unit of a figure.
PER_UNIT = {"latency": 2, "throughput": 1}
SIZES = {"100": "100 B", "10000": "10 kB", "1000000": "1 MB"}
FIGURES = (
    ("latency", 50.0, "round trip p50 (pooled)", "µs", False),
    ("latency", 99.0, "round trip p99 (pooled)", "µs", False),
    ("throughput", None, "one-way message rate", "msg/s", True),
)


def speed(extra):
    """Instructions per nanosecond at which this machine runs liblcm's own code: C's memq://
    loop, its counted instructions over its slowest timed run (IPNS without them)."""
    times = extra.get("loop_time", [])
    per_msg = extra.get("c", {}).get("100")
    if not times or per_msg is None:
        return IPNS
    return min(per_msg * count / (secs * 1e9) for count, secs in times)


def method(resamples=RESAMPLES):
    return (
        "Method (`scripts/bench-lcm-table.py`; method 1 fixed before runs 1 and 2, method 2 from "
        "run 3 on, its counted rate settled after run 3 was timed, which changed no verdict): "
        "latency figures are "
        "the pooled percentiles of every round trip of every round; throughput is all messages of "
        "all rounds over the time they took. Each ratio's 95 % interval resamples the rounds "
        f"({resamples} resamples, fixed seed; a round's C, Rust and control runs kept together). "
        "Verdict: *holds* when the whole interval is within the bar (Rust / C ≤ 1.05 for times, "
        "≥ 0.95 for rates), *fails* when the whole interval is outside it; a message Rust lost "
        "fails the figure. Where the interval straddles the bar (or C lost a message), the exact "
        "count decides (*holds (counted)*, *fails (counted)*): both programs make the same liblcm "
        "calls, so what Rust adds is user-space instructions, counted by callgrind per message at "
        "that size (publish + dispatch on memq://); the instructions Rust adds per unit of the "
        "figure (a round trip carries two messages, a streamed message one), at the speed this "
        "machine runs liblcm's own instructions (C's memq:// loop of a million messages, its "
        "count over the slowest of three timed runs), over C's time for the unit, give the "
        "ratio Rust would show without noise (the *counted* column)."
    )


def load(path):
    rows, extra = [], {}
    for line in open(path):
        f = dict(kv.split("=", 1) for kv in line.split() if "=" in kv)
        if f.get("mode") == "instructions":
            extra.setdefault(f["who"], {})[f.get("size", "100")] = int(f["per_msg"])
        elif f.get("mode") == "loop_time":
            extra.setdefault("loop_time", []).append((int(f["count"]), float(f["secs"])))
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


def within(ratio, higher):
    return ratio >= 1 - BAR if higher else ratio <= 1 + BAR


def counted(extra, size, mode, c_value, higher, ipns):
    """The Rust / C ratio the exact counts give the figure (C's measured value `c_value`, in µs
    or msg/s): C's time per unit plus what Rust adds at IPNS; None without both counts."""
    try:
        added = extra["rust"][size] - extra["c"][size]
    except KeyError:
        return None
    unit_ns = 1e9 / c_value if higher else c_value * 1e3
    share = added * PER_UNIT[mode] / ipns / unit_ns
    return 1 / (1 + share) if higher else 1 + share


def verdict(lo, hi, higher, lost_c, lost_r, by_count):
    if lost_r:
        return "fails"
    if not lost_c:
        if within(lo, higher) and within(hi, higher):
            return "holds"
        if not within(lo, higher) and not within(hi, higher):
            return "fails"
    if by_count is None:
        return "not shown"
    return "holds (counted)" if within(by_count, higher) else "fails (counted)"


def table(rows, extra):
    rng = random.Random(1)
    out = [
        "| size | figure | C (liblcm) | Rust (lcm crate) | Rust / C | 95 % interval | bar "
        "| C again / C (A/A control) | control's 95 % interval | lost C / Rust "
        "| counted Rust / C | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
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
            k = counted(extra, size, mode, c, higher, speed(extra))
            v = verdict(lo, hi, higher, lost_c, lost_r, k)
            counts[v.split(" (")[0]] += 1
            if not v.startswith("holds"):
                unresolved.append(f"{sz} {label.split(' (')[0]} ({v})")
            kc = "—" if k is None else f"{k:.4f}"
            bar = "≥ 0.95" if higher else "≤ 1.05"
            fmt = (lambda x: f"{x:.1f}") if unit == "µs" else (lambda x: f"{x:.0f}")
            out.append(
                f"| {sz} | {label} | {fmt(c)} {unit} | {fmt(r)} {unit} | {r / c:.3f} "
                f"| {lo:.3f} to {hi:.3f} | {bar} | {cc / c:.3f} | {clo:.3f} to {chi:.3f} "
                f"| {lost_c} / {lost_r} | {kc} | {v} |"
            )
            if mode == "throughput":
                mb = lambda x: x * int(size) / 1e6  # noqa: E731
                out.append(
                    f"| {sz} | one-way throughput (the rate in MB/s) | {mb(c):.1f} MB/s "
                    f"| {mb(r):.1f} MB/s | {r / c:.3f} | {lo:.3f} to {hi:.3f} | {bar} "
                    f"| {cc / c:.3f} | {clo:.3f} to {chi:.3f} | {lost_c} / {lost_r} | {kc} | {v} |"
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
        out.append("")
        parts = [
            f"{sz}: C {extra['c'][size]}, Rust {extra['rust'][size]} "
            f"({extra['rust'][size] - extra['c'][size]:+d})"
            for size, sz in SIZES.items()
            if size in extra["c"] and size in extra["rust"]
        ]
        out.append(
            "Library cost in user space, instructions per message (callgrind, publish + dispatch "
            "on memq://, exact and repeatable): " + "; ".join(parts) + f". This machine runs "
            f"liblcm's own instructions at {speed(extra):.2f} per nanosecond (C's loop, the "
            "slowest of its timed runs): the rate the counted column adds them at."
        )
    summary = (n_rounds, counts, unresolved)
    return "\n".join(out), summary


RUNS_START, RUNS_END = "<!-- lcm-runs:start -->", "<!-- lcm-runs:end -->"
RUNS_HEAD = [
    "| run | date | commit | rounds | method | hold | not shown | fail | figures not shown to hold |",
    "|---|---|---|---|---|---|---|---|---|",
]
# 1: timed intervals only; 2: the exact count decides where the interval cannot.
METHOD = "2"


def history(path):
    """The rows of the list of full runs in BENCHMARKS.md (written only by this script)."""
    try:
        text = open(path).read()
    except OSError:
        return []
    m = re.search(re.escape(RUNS_START) + "(.*?)" + re.escape(RUNS_END), text, re.S)
    if not m:
        return []
    rows = [
        line for line in m.group(1).splitlines()
        if line.startswith("| ") and not line.startswith("| run ") and not line.startswith("|---")
    ]
    # Rows from before the method column were made with method 1.
    fixed = []
    for line in rows:
        cells = line.split(" | ")
        if len(cells) == 8:
            cells.insert(4, "1")
        fixed.append(" | ".join(cells))
    return fixed


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
            f"| {len(runs) + 1} | {date} | {commit} | {n_rounds} | {METHOD} | {counts['holds']} "
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
