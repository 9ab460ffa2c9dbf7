#!/usr/bin/env bash
# Tilted- and turning-tool removal against the vertical original, per tool shape, on the
# Fusion 360 adaptive example (see README.md). Usage: examples/tilted/bench.sh [OUT_DIR]
# Needs a release build (cargo build --release) and python3 for the summary lines.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
out=${1:-$root/results/tilted}
bin=${MILLSIM:-$root/target/release/millsim}
src=$root/examples/adaptive/1055_utab_265bit.nc
mkdir -p "$out"
# 3+2: the same program with the table turned to A15 before the first move.
awk '/^G54$/ && !done {print; print "G0 A15"; done=1; next} {print}' "$src" >"$out/tilted_a15.nc"
# Turning: every straight feed move after that also rocks A between 14° and 16°.
awk '
  /^G54$/ && !done {print; print "G0 A15"; done=1; on=1; next}
  { if ($0 ~ /(^|[^0-9])G0?0([^0-9]|$)/) mode=0
    if ($0 ~ /(^|[^0-9])G0?1([^0-9]|$)/) mode=1
    if ($0 ~ /(^|[^0-9])G0?[23]([^0-9]|$)/) mode=2 }
  on && mode==1 && $0 ~ /[XY]-?[0-9.]/ { printf "%s A%s\n", $0, (i++ % 2 ? "16" : "14"); next }
  {print}' "$src" >"$out/turning_a14_a16.nc"
run() { # NAME PROGRAM MACHINE TOOL
  /usr/bin/time -f "%U %S %e %M" -o "$out/$1.time" "$bin" run --stock "$root/examples/adaptive/stock.json" \
    --program "$2" --machine "$3" --tool "T1=$4" --material Al7075-T6 --out "$out/$1" >/dev/null 2>"$out/$1.err"
  python3 - "$out" "$1" <<'PY'
import json, sys
out, name = sys.argv[1:]
s = json.load(open(f"{out}/{name}/summary.json"))
u, sy, wall, rss = open(f"{out}/{name}.time").read().split()
t = s["timings"]["removal_and_engagement_s"]
print(f"{name:16} updates {s['dexel_updates']:>11} removal {t:6.2f} s {s['dexel_updates'] / t / 1e6:6.1f} M/s"
      f"  cpu {float(u) + float(sy):6.2f} s  wall {wall} s  peak {int(rss) // 1024} MB  volume {s['removed_volume_mm3']:.2f} mm3")
PY
}
for t in flat ball bull chamfer; do
  run "vertical_$t" "$src" "$root/examples/adaptive/machine.json" "$here/tool_$t.json"
  run "a15_$t" "$out/tilted_a15.nc" "$here/machine_xyza.json" "$here/tool_$t.json"
  run "turning_$t" "$out/turning_a14_a16.nc" "$here/machine_xyza.json" "$here/tool_$t.json"
done
