"""Criterion benches of two builds, alternated in one run: old, new, old, new per bench target.
Prints the median time per benchmark and the ratio new/old (median of the per-round ratios).

    python3 compare_builds.py OLD_TARGET/release/deps NEW_TARGET/release/deps
    ROUNDS=3 TARGETS='contact=contact/tree/' python3 compare_builds.py ...

Build each side first with `cargo bench --no-run --bench sat --bench lookup --bench voxelize
--bench contact`; the newest binary of each name in each directory is run.
"""
import re, subprocess, sys, statistics, os
old_dir, new_dir = sys.argv[1], sys.argv[2]   # target/release/deps of each
targets = dict(x.split('=',1) for x in os.environ['TARGETS'].split(';')) if os.environ.get('TARGETS') else {'sat': 'sat_overlaps_voxel', 'lookup': '.', 'voxelize': 'fill_and_layers|voxelize/demo', 'contact': 'contact/tree/'}
rounds = int(os.environ.get('ROUNDS', '2'))
unit = {'ps':1e-12,'ns': 1e-9, 'µs': 1e-6, 'us': 1e-6, 'ms': 1e-3, 's': 1.0}
def binary(d, name):
    c = [f for f in os.listdir(d) if re.fullmatch(name + r'-[0-9a-f]{16}', f)]
    return max((os.path.join(d, f) for f in c), key=os.path.getmtime)
def run(b, filt):
    out = subprocess.run([b, '--bench', filt, '--warm-up-time', '1', '--measurement-time', '3', '--noplot'],
                         capture_output=True, text=True, cwd=os.path.dirname(b)).stdout
    res = {}; name = None
    for line in out.split('\n'):
        m = re.match(r'^(\S.*?)\s+time:\s+\[(\S+) (\S+) (\S+) (\S+) (\S+) (\S+)\]', line)
        if m:
            res[m.group(1).strip()] = float(m.group(4)) * unit[m.group(5)]; continue
        m = re.match(r'^\s+time:\s+\[(\S+) (\S+) (\S+) (\S+) (\S+) (\S+)\]', line)
        if m and name:
            res[name] = float(m.group(3)) * unit[m.group(4)]; continue
        if line and not line.startswith(' ') and 'time:' not in line and not line.startswith(('Benchmarking','Found','Warning','Gnuplot')):
            name = line.strip()
    return res
rows = {}
for t, filt in targets.items():
    ob, nb = binary(old_dir, t), binary(new_dir, t)
    for r in range(rounds):
        for which, b in (('old', ob), ('new', nb)):
            for k, v in run(b, filt).items():
                rows.setdefault((t, k), {'old': [], 'new': []})[which].append(v)
        print(f'# {t} round {r+1} done', file=sys.stderr, flush=True)
print('| bench | old (median) | new (median) | new/old |')
print('|---|---:|---:|---:|')
def fmt(s):
    for u, f in (('s',1),('ms',1e-3),('µs',1e-6),('ns',1e-9)):
        if s >= f: return f'{s/f:.3g} {u}'
    return f'{s*1e12:.3g} ps'
allr = []
for (t, k), v in rows.items():
    if not v['old'] or not v['new']: continue
    ratios = [n / o for o, n in zip(v['old'], v['new'])]
    rr = statistics.median(ratios); allr.append(rr)
    print(f"| {k} | {fmt(statistics.median(v['old']))} | {fmt(statistics.median(v['new']))} | {rr:.3f} |")
print(f'\ngeometric mean of ratios: {statistics.geometric_mean(allr):.3f} over {len(allr)} benchmarks')
