#!/usr/bin/env python3
"""Which queries make the latency's tail of a `vps haptics-bench --samples FILE` run.

    python3 crates/vps/benches/sweep_tail.py samples.csv [more.csv ...]

For each file: p50 and p99 of every query and of the passes after the first (the cache
warm); a least-squares line of microseconds against points tested over the queries that
test any; the p99 that line predicts from each query's work alone; and of the slowest 1 %,
how many ran in the first pass within the first 200 queries that test points (the bricks of
the contact still being decoded). Standard library only.
"""
import csv
import math
import sys


def percentile(xs, q):
    """Nearest rank, as `vps haptics-bench` computes its p50 and p99."""
    xs = sorted(xs)
    if not xs:
        return float("nan")
    rank = max(1, math.ceil(q / 100 * len(xs)))
    return xs[rank - 1]


def line(xs, ys):
    n = len(xs)
    mx, my = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx else 0.0
    return slope, my - slope * mx


def report(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    us = [float(r["micros"]) for r in rows]
    tested = [int(r["points_tested"]) for r in rows]
    passes = [int(r["pass"]) for r in rows]
    warm = [u for u, p in zip(us, passes) if p > 0]
    busy = [(t, u) for t, u in zip(tested, us) if t > 0]
    if not busy:
        print(f"{path}: no query tests any point")
        return
    slope, icept = line([t for t, _ in busy], [u for _, u in busy])
    predicted = [slope * t + icept for t in tested]
    first_busy = [i for i, (t, p) in enumerate(zip(tested, passes)) if t > 0 and p == 0][:200]
    cold = set(first_busy)
    n_slow = max(1, len(us) // 100)
    slowest = sorted(range(len(us)), key=lambda i: us[i])[-n_slow:]
    in_cold = sum(i in cold for i in slowest)
    print(f"{path}: {len(us)} queries")
    print(f"  all:  p50 {percentile(us, 50):7.1f} us  p99 {percentile(us, 99):7.1f} us")
    if warm:
        print(f"  warm: p50 {percentile(warm, 50):7.1f} us  p99 {percentile(warm, 99):7.1f} us (passes after the first)")
    print(f"  line: {1000 * slope:.2f} ns a point tested + {icept:.1f} us; p99 of its prediction {percentile(predicted, 99):7.1f} us")
    print(f"  slowest {n_slow}: {in_cold} in the first pass's first 200 queries that test points;"
          f" mean {sum(us[i] for i in slowest) / n_slow:.1f} us against {sum(predicted[i] for i in slowest) / n_slow:.1f} predicted")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    for p in sys.argv[1:]:
        report(p)
