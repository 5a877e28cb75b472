#!/usr/bin/env bash
# Side by side: `vps voxelize` against OpenVDB 10's tools::meshToLevelSet (C++ peer of the
# shared peer harness), same mesh, same voxel size, half width = layers, all threads.
#
#   benches/peers.sh MESH VOXEL_SIZE [LAYERS]     one case (LAYERS default 5)
#   benches/peers.sh --default [LAYERS]           the default list (dragon, two CAD models,
#                                                 terrain; ~1e8 and ~1e9 bounding-box voxels)
#
# MESH is .obj or .obj.zst; a bare file name is also looked up in $MESHES_DIR. VOXEL_SIZE may
# be written @N (e.g. @1e8): the size whose bounding-box grid holds about N voxels, from the
# harness's voxel_size_for.py (needs numpy in $NUMPY_PYTHON).
#
# Output: one markdown table row per case on stdout (header first), progress on stderr.
#
# Environment:
#   PEERS_DIR     peer harness with openvdb_cpp/vdb_voxelize built (default $REPO/../shared/peers)
#   MESHES_DIR    where bare mesh names are looked up (default $REPO/../shared/data/meshes)
#   REPEAT        runs per side and case, order alternating; medians are reported (default 3)
#   TIMEOUT       seconds per run; a case where either side exceeds it is skipped (default 600)
#   BUILD         1: `cargo build --release` first (default); 0: use the existing binary
#   VPS_BIN       our binary (default $CARGO_TARGET_DIR or $REPO/target, then release/vps);
#                 it is copied to a temp dir so that a concurrent rebuild cannot change it mid-run
#   VDB_EXTRAS    1: let the peer also compute its untimed extras (interior mask, shell counts);
#                 default 0 (--no-extras), so its peak RSS covers load + conversion only
#   OUT           append every raw run (JSON lines) and one summary line per case to this file
#   PY3           python3 used for JSON parsing (default python3; no third-party modules)
#   NUMPY_PYTHON  python with numpy, for @N voxel sizes (default /usr/bin/python3)
#   WORK_DIR      where temp files go: decompressed meshes, .vxm outputs (default $TMPDIR or /tmp)
#
# A .obj.zst mesh is decompressed once per invocation (the C++ peer reads plain .obj only) and
# BOTH sides are given the same decompressed file. Neither side's timing includes loading.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO="$(cd "$HERE/.." && pwd)"
SHARED="${SHARED_DIR:-$REPO/../shared}"
PEERS_DIR="${PEERS_DIR:-$SHARED/peers}"
MESHES_DIR="${MESHES_DIR:-$SHARED/data/meshes}"
REPEAT="${REPEAT:-3}"
TIMEOUT="${TIMEOUT:-600}"
BUILD="${BUILD:-1}"
VDB_EXTRAS="${VDB_EXTRAS:-0}"
OUT="${OUT:-}"
PY3="${PY3:-python3}"
NUMPY_PYTHON="${NUMPY_PYTHON:-/usr/bin/python3}"
VDB="$PEERS_DIR/openvdb_cpp/vdb_voxelize"

# Default list: mesh and voxel sizes giving bounding-box grids of about 1e8 and 1e9 voxels
# (voxel_size_for.py, rounded to 2-3 significant digits).
DEFAULT_CASES="
stanford_dragon.obj.zst 0.0003
stanford_dragon.obj.zst 0.00014
racecar_assembly.obj 0.00058
racecar_assembly.obj 0.00027
differential_gears.obj 0.000185
differential_gears.obj 0.0000857
terrain_hawaii.obj.zst 338
terrain_hawaii.obj.zst 157
"

usage() { sed -n '2,31p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
say() { echo "peers.sh: $*" >&2; }

case "${1:-}" in
  -h|--help|"") usage; [ -n "${1:-}" ] && exit 0; exit 2 ;;
esac

# ---------------------------------------------------------------- prerequisites
if [ ! -x "$VDB" ]; then
  cat >&2 <<EOF
peers.sh: the OpenVDB C++ peer is not built: $VDB is missing.
To set it up (Debian 12, as root; see the harness's README.md):
  cp -r "$PEERS_DIR" /some/writable/dir/peers
  /some/writable/dir/peers/setup.sh          # or SKIP_APT=1 ... if the apt packages are there
  PEERS_DIR=/some/writable/dir/peers $0 $*
EOF
  echo "skipped: OpenVDB peer not available (set PEERS_DIR to a built copy of the peer harness)"
  exit 0
fi
if [ ! -x /usr/bin/time ]; then
  say "/usr/bin/time is missing (apt-get install time; the harness's setup.sh installs it)"
  echo "skipped: /usr/bin/time not available"
  exit 0
fi
case "$REPEAT" in ''|*[!0-9]*|0) say "REPEAT must be a positive integer, got '$REPEAT'"; exit 2 ;; esac
command -v timeout >/dev/null || { say "coreutils timeout is missing"; exit 1; }
command -v "$PY3" >/dev/null || { say "python3 is missing (set PY3)"; exit 1; }

WORK="$(mktemp -d "${WORK_DIR:-${TMPDIR:-/tmp}}/vps-peers.XXXXXX")"
trap 'rm -rf "$WORK"' EXIT

if [ "$BUILD" = 1 ] && [ -z "${VPS_BIN:-}" ]; then
  say "cargo build --release"
  (cd "$REPO" && cargo build --release --quiet) >&2
fi
VPS_BIN="${VPS_BIN:-${CARGO_TARGET_DIR:-$REPO/target}/release/vps}"
[ -x "$VPS_BIN" ] || { say "$VPS_BIN is missing (run cargo build --release, or set VPS_BIN)"; exit 1; }
cp "$VPS_BIN" "$WORK/vps"

# ---------------------------------------------------------------- helpers
resolve_mesh() {  # MESH -> existing path
  local p
  if [ -f "$1" ]; then p="$1"
  elif [ -f "$MESHES_DIR/$1" ]; then p="$MESHES_DIR/$1"
  else say "mesh not found: $1 (nor in MESHES_DIR=$MESHES_DIR)"; return 1
  fi
  echo "$(cd "$(dirname "$p")" && pwd)/$(basename "$p")"
}

plain_obj() {  # MESH path -> plain .obj path (decompressed once into $WORK)
  case "$1" in
    *.zst)
      local out; out="$WORK/$(basename "${1%.zst}")"
      if [ ! -f "$out" ]; then
        command -v zstd >/dev/null || { say "zstd is needed to decompress $1"; return 1; }
        say "decompressing $(basename "$1")"
        zstd -q -d -f -o "$out" "$1"
      fi
      echo "$out" ;;
    *) echo "$1" ;;
  esac
}

voxel_size() {  # OBJ SPEC -> voxel size (SPEC is a number or @N)
  case "$2" in
    @*) (cd "$PEERS_DIR" && "$NUMPY_PYTHON" voxel_size_for.py "$1" "${2#@}") ;;
    *) echo "$2" ;;
  esac
}

# run_one SIDE REP CASE_ID CMD... : one timed run, one JSON record appended to $WORK/runs.jsonl
run_one() {
  local side="$1" rep="$2" case_id="$3"; shift 3
  local tv="$WORK/time.txt" so="$WORK/stdout.txt" se="$WORK/stderr.txt" rc=0 la
  la="$(cut -d' ' -f1 /proc/loadavg)"
  say "  [$case_id] rep $rep: $side"
  /usr/bin/time -v -o "$tv" timeout -k 10 "$TIMEOUT" "$@" </dev/null >"$so" 2>"$se" || rc=$?
  rm -f "$WORK/out.vxm"
  "$PY3" - "$side" "$rep" "$case_id" "$rc" "$la" "$TIMEOUT" "$tv" "$so" "$se" \
      >>"$WORK/runs.jsonl" <<'EOF'
import json, re, sys
side, rep, case_id, rc, la, tmo, tv, so, se = sys.argv[1:]
rc = int(rc)
out = None
for line in reversed(open(so, errors="replace").read().splitlines()):
    line = line.strip()
    if line.startswith("{"):
        try:
            out = json.loads(line)
            break
        except ValueError:
            pass
tvs = open(tv, errors="replace").read()
def field(pat):
    m = re.search(pat, tvs)
    return m.group(1) if m else None
rss = field(r"Maximum resident set size \(kbytes\): (\d+)")
cpu = field(r"Percent of CPU this job got: (\d+)%")
user = field(r"User time \(seconds\): ([0-9.]+)")
system = field(r"System time \(seconds\): ([0-9.]+)")
if out is not None and rc == 0:
    status = "ok"
elif rc in (124, 137) or "signal 9" in tvs:
    status = "timeout"
else:
    status = "error"
rec = {"side": side, "rep": int(rep), "case": case_id, "status": status, "rc": rc,
       "loadavg1_before": float(la), "timeout_s": float(tmo),
       "time_v_max_rss_mib": round(int(rss) / 1024.0, 1) if rss else None,
       "time_v_cpu_percent": int(cpu) if cpu else None,
       "time_v_cpu_s": round(float(user) + float(system), 3) if user and system else None,
       "out": out}
if status == "error":
    err = open(se, errors="replace").read().strip().splitlines()
    rec["error"] = err[-1][:300] if err else ""
print(json.dumps(rec))
EOF
  [ -z "$OUT" ] || tail -n 1 "$WORK/runs.jsonl" >>"$OUT"
  tail -n 1 "$WORK/runs.jsonl" | "$PY3" -c 'import json,sys; r=json.loads(sys.stdin.read()); sys.exit(0 if r["status"]=="ok" else 1)'
}

header_done=0
print_header() {
  [ "$header_done" = 1 ] && return
  header_done=1
  echo "| mesh | triangles | voxel size | grid voxels (ours) | ours s (total, incl. write) | ours s (surface+fill+layers) | openvdb s | openvdb/ours (total) | openvdb/ours (generation) | ours peak RSS MiB | openvdb peak RSS MiB | our file bytes | openvdb active voxels | our surface voxels |"
  echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
}

n_failed=0
case_no=0
# run_case MESH VOXEL_SPEC LAYERS
run_case() {
  local mesh="$1" spec="$2" layers="$3" path obj vs case_id r first second failed=""
  case_no=$((case_no + 1))
  path="$(resolve_mesh "$mesh")" && obj="$(plain_obj "$path")" && vs="$(voxel_size "$obj" "$spec")" || {
    say "case $mesh $spec: cannot prepare it, skipped"
    n_failed=$((n_failed + 1))
    return 0
  }
  case_id="$(basename "$path")@$vs"
  say "case $case_id, layers $layers, $REPEAT run(s) per side, timeout ${TIMEOUT}s"
  local vdb_args=(--mode ls --half-width "$layers" --threads 0)
  [ "$VDB_EXTRAS" = 1 ] || vdb_args+=(--no-extras)
  for ((r = 1; r <= REPEAT; r++)); do
    # alternate who goes first, across repetitions and across cases
    if [ $(((r + case_no) % 2)) = 0 ]; then first=ours; second=openvdb; else first=openvdb; second=ours; fi
    for side in "$first" "$second"; do
      if [ "$side" = ours ]; then
        run_one ours "$r" "$case_id" "$WORK/vps" voxelize "$obj" --voxel-size "$vs" \
          --layers "$layers" -o "$WORK/out.vxm" --json || failed=1
      else
        run_one openvdb "$r" "$case_id" "$VDB" "$obj" "$vs" "${vdb_args[@]}" || failed=1
      fi
      [ -z "$failed" ] || break
    done
    [ -z "$failed" ] || break
  done
  print_header
  "$PY3" - "$case_id" "$(basename "$path")" "$vs" "$layers" "$WORK/runs.jsonl" "${OUT:-}" <<'EOF' || n_failed=$((n_failed + 1))
import json, statistics, sys
case_id, mesh, vs, layers, runs, out_path = sys.argv[1:]
recs = [json.loads(l) for l in open(runs) if l.strip()]
recs = [r for r in recs if r["case"] == case_id]
bad = [r for r in recs if r["status"] != "ok"]
dash = " – |" * 10
if bad:
    b = bad[0]
    if b["status"] == "timeout":
        why = "skipped: %s exceeded TIMEOUT=%g s" % (b["side"], b["timeout_s"])
    else:
        why = "error: %s rc=%d %s" % (b["side"], b["rc"], b.get("error", ""))
    print("| %s | – | %s | %s |%s" % (mesh, vs, why.replace("|", "/"), dash))
    summary = {"summary": case_id, "status": bad[0]["status"], "why": why}
    rc = 0 if b["status"] == "timeout" else 1
else:
    ours = [r for r in recs if r["side"] == "ours"]
    vdb = [r for r in recs if r["side"] == "openvdb"]
    med = lambda xs: statistics.median(xs)
    o0, v0 = ours[0]["out"], vdb[0]["out"]
    o_total = med([r["out"]["seconds"] for r in ours])
    o_gen = med([r["out"]["surface_seconds"] + r["out"]["fill_seconds"] + r["out"]["layers_seconds"]
                 for r in ours])
    v_wall = med([r["out"]["wall_s"] for r in vdb])
    o_rss = med([r["time_v_max_rss_mib"] for r in ours])
    v_rss = med([r["time_v_max_rss_mib"] for r in vdb])
    tris = o0["triangles"] + o0.get("degenerate_skipped", 0)
    def g(x):
        return "%.3g" % x if x < 100 else "%.0f" % x
    print("| %s | %s | %s | %s | %s | %s | %s | %.2f | %.2f | %.0f | %.0f | %s | %s | %s |" % (
        mesh, format(tris, ","), vs, format(o0["grid_voxels"], ","), g(o_total), g(o_gen),
        g(v_wall), v_wall / o_total, v_wall / max(o_gen, 1e-9), o_rss, v_rss,
        format(o0["file_bytes"], ","), format(v0["active_voxels"], ","),
        format(o0["surface_voxels"], ",")))
    summary = {"summary": case_id, "status": "ok", "mesh": mesh, "voxel_size": float(vs),
               "layers": int(layers), "repeat": len(ours), "triangles": tris,
               "degenerate_skipped": o0.get("degenerate_skipped"),
               "grid_voxels": o0["grid_voxels"], "bbox_voxels": v0.get("bbox_voxels"),
               "ours_seconds": o_total, "ours_generation_seconds": o_gen,
               "openvdb_wall_s": v_wall, "ratio_total": v_wall / o_total,
               "ratio_generation": v_wall / max(o_gen, 1e-9),
               "ours_peak_rss_mib": o_rss, "openvdb_peak_rss_mib": v_rss,
               "ours_process_cpu_s": med([r["time_v_cpu_s"] or 0 for r in ours]),
               "openvdb_process_cpu_s": med([r["time_v_cpu_s"] or 0 for r in vdb]),
               "openvdb_conversion_cpu_s": med([r["out"]["cpu_s"] for r in vdb]),
               "openvdb_cpu_over_wall": med([r["out"]["cpu_s"] / max(r["out"]["wall_s"], 1e-9) for r in vdb]),
               "file_bytes": o0["file_bytes"], "openvdb_active_voxels": v0["active_voxels"],
               "surface_voxels": o0["surface_voxels"], "inner_voxels": o0.get("inner_voxels"),
               "leaks": o0.get("leaks"),
               "loadavg1_before_max": max(r["loadavg1_before"] for r in recs)}
    rc = 0
sys.stdout.flush()
if out_path:
    with open(out_path, "a") as fh:
        fh.write(json.dumps(summary) + "\n")
sys.exit(rc)
EOF
}

# ---------------------------------------------------------------- main
if [ "$1" = --default ]; then
  layers="${2:-5}"
  read -r -d '' -a cases <<<"$DEFAULT_CASES" || true  # mesh size mesh size ...
  for ((i = 0; i + 1 < ${#cases[@]}; i += 2)); do
    run_case "${cases[i]}" "${cases[i + 1]}" "$layers"
  done
else
  [ $# -ge 2 ] || { usage; exit 2; }
  run_case "$1" "$2" "${3:-5}"
fi
[ "$n_failed" = 0 ] || { say "$n_failed case(s) failed"; exit 1; }
