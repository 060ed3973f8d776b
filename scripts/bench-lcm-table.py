#!/usr/bin/env python3
"""Turns the raw lines of `scripts/bench lcm` into its Markdown table.

Per figure: C, Rust and the C control (a copy of the C binary), the ratio Rust / C with a 95 %
bootstrap interval (rounds resampled with replacement, C, Rust and control of a round kept
together), and a verdict against the bar: pass (the ratio is within it), FAIL (the whole
interval is outside it), or unclear (the ratio misses but the interval reaches the bar).
Latency figures are the lower quartile over rounds of each run's percentile: on this kind of
machine the per-run figures fall in two modes (undisturbed, and disturbed by the host), and the
lower quartile tracks the undisturbed one; of the median, mean, trimmed mean, minimum and
lower quartile it was the statistic whose A/A control strayed least. Throughput is all
messages of all rounds over the time they took.
"""
import random
import statistics
import sys

BAR = 0.05
RESAMPLES = 2000


def load(path):
    rows, extra = [], {}
    for line in open(path):
        f = dict(kv.split("=", 1) for kv in line.split() if "=" in kv)
        if f.get("mode") == "instructions":
            extra[f["who"]] = int(f["per_msg"])
        elif "round" in f:
            rows.append(f)
    return rows, extra


def estimate(runs, metric):
    if metric == "rate":
        msgs = sum(float(r["count"]) - float(r["lost"]) for r in runs)
        secs = sum((float(r["count"]) - float(r["lost"])) / float(r["msgs_per_s"]) for r in runs)
        return msgs / secs if secs > 0 else 0.0
    values = sorted(float(r[metric]) for r in runs)
    return values[len(values) // 4]


def main(path):
    rows, extra = load(path)
    rng = random.Random(1)
    out = [
        "| size | figure | C (liblcm) | Rust (lcm crate) | Rust / C | 95 % interval | bar | C again / C (noise floor) | lost C / Rust | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    counts = {"pass": 0, "unclear": 0, "FAIL": 0}
    n_rounds = 0
    for size in ("100", "10000", "1000000"):
        for mode, metric, label, unit, higher in (
            ("latency", "p50_us", "round trip p50", "µs", False),
            ("latency", "p99_us", "round trip p99", "µs", False),
            ("throughput", "rate", "one-way message rate", "msg/s", True),
        ):
            by_round = {}
            for r in rows:
                if r["mode"] == mode and r["size"] == size:
                    by_round.setdefault(r["round"], {})[r["who"]] = r
            rounds = [v for v in by_round.values() if {"c", "cc", "rust"} <= v.keys()]
            n_rounds = max(n_rounds, len(rounds))
            if not rounds:
                continue

            def ratios(sample):
                c = estimate([v["c"] for v in sample], metric)
                return (
                    c,
                    estimate([v["rust"] for v in sample], metric),
                    estimate([v["cc"] for v in sample], metric),
                )

            c, r, cc = ratios(rounds)
            boot = []
            for _ in range(RESAMPLES):
                s = [rng.choice(rounds) for _ in rounds]
                bc, br, _ = ratios(s)
                boot.append(br / bc)
            boot.sort()
            lo, hi = boot[int(0.025 * RESAMPLES)], boot[int(0.975 * RESAMPLES) - 1]
            ratio = r / c
            if higher:
                ok, clear_miss, bar = ratio >= 1 - BAR, hi < 1 - BAR, "≥ 0.95"
            else:
                ok, clear_miss, bar = ratio <= 1 + BAR, lo > 1 + BAR, "≤ 1.05"
            lost_c = sum(int(v["c"]["lost"]) for v in rounds)
            lost_r = sum(int(v["rust"]["lost"]) for v in rounds)
            verdict = "pass" if ok and lost_c + lost_r == 0 else ("FAIL" if clear_miss or lost_r else "unclear")
            counts[verdict] += 1
            sz = {"100": "100 B", "10000": "10 kB", "1000000": "1 MB"}[size]
            fmt = (lambda x: f"{x:.1f}") if unit == "µs" else (lambda x: f"{x:.0f}")
            out.append(
                f"| {sz} | {label} | {fmt(c)} {unit} | {fmt(r)} {unit} | {ratio:.3f} | {lo:.3f} to {hi:.3f} "
                f"| {bar} | {cc / c:.3f} | {lost_c} / {lost_r} | {verdict} |"
            )
            if mode == "throughput":
                mb = lambda x: x * int(size) / 1e6  # noqa: E731
                out.append(
                    f"| {sz} | one-way throughput | {mb(c):.1f} MB/s | {mb(r):.1f} MB/s | {ratio:.3f} | {lo:.3f} to {hi:.3f} "
                    f"| {bar} | {cc / c:.3f} | {lost_c} / {lost_r} | {verdict} |"
                )
    out.append("")
    out.append(
        f"{counts['pass']} of 9 figures pass, {counts['unclear']} unclear, {counts['FAIL']} fail "
        f"({n_rounds} rounds; the throughput rows repeat the message rate in MB/s)."
    )
    if "c" in extra and "rust" in extra:
        lat = [v for v in rows if v["mode"] == "latency" and v["size"] == "100" and v["who"] == "c"]
        p50 = estimate(lat, "p50_us") if lat else 0
        d = extra["rust"] - extra["c"]
        out.append("")
        out.append(
            f"Library cost in user space (callgrind, publish + dispatch of a 100-byte message on memq://): "
            f"C {extra['c']} instructions per message, Rust {extra['rust']} (the wrapper adds {d}, about "
            f"{d / 2500:.2f} µs at 2.5 instructions/ns, against a {p50:.0f} µs round trip)."
        )
    print("\n".join(out))


if __name__ == "__main__":
    main(sys.argv[1])
