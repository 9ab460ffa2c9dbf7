#!/usr/bin/env bash
# Issue 32's acceptance figure: simultaneous 5-axis removal (the corpus impeller, axes
# turning all the time, 0.1 mm grid) against vertical removal (the Fusion 360 adaptive
# example, 0.05 mm), as dexel updates per second of removal and engagement, in rounds
# that alternate the two runs (this machine's wall time drifts by ±20% over minutes, so
# one pair of runs says little; the medians over the rounds are the figure).
# Usage: examples/tilted/ratio.sh [ROUNDS] [OUT_DIR]   (defaults: 5, results/ratio)
# Needs a release build (cargo build --release), python3, and the impeller program from
# the shared corpus ($MILLSIM_CORPUS, else ../shared/corpus beside the repository).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
rounds=${1:-5}
out=${2:-$root/results/ratio}
bin=${MILLSIM:-$root/target/release/millsim}
corpus=${MILLSIM_CORPUS:-$root/../shared/corpus}
impeller=$corpus/gcode/linuxcnc_5axis_impeller_7bl_xyzac_g93.ngc
if [ ! -f "$impeller" ]; then
  echo "skipped: no impeller program at $impeller (set MILLSIM_CORPUS to the shared corpus)" >&2
  exit 2
fi
[ -x "$bin" ] || { echo "no release build at $bin: run cargo build --release" >&2; exit 1; }
ad=$root/examples/adaptive
mkdir -p "$out"
run() { # NAME ARGS...
  local name=$1; shift
  /usr/bin/time -f "%e %M" -o "$out/$name.time" "$bin" run "$@" --out "$out/$name" >/dev/null 2>"$out/$name.err"
}
for r in $(seq 1 "$rounds"); do
  run "impeller_$r" --stock "$here/impeller/stock.json" --program "$impeller" --tool "T1=$here/impeller/tool.json" \
    --material TC6 --machine "$here/impeller/machine.json" --axes tool_tip --resolution 0.1
  run "adaptive_$r" --stock "$ad/stock.json" --program "$ad/1055_utab_265bit.nc" --tool "T1=$ad/tool.json" \
    --material Al7075-T6 --machine "$ad/machine.json" --optimize max_force=400,air_feed=5000,max_feed=5000 --resolution 0.05
  python3 - "$out" "$r" <<'PY'
import json, sys
out, r = sys.argv[1:]
line = []
for name in ("impeller", "adaptive"):
    s = json.load(open(f"{out}/{name}_{r}/summary.json"))
    wall, rss = open(f"{out}/{name}_{r}.time").read().split()
    t = s["timings"]["removal_and_engagement_s"]
    rate = s["dexel_updates"] / t / 1e6
    json.dump({"rate": rate, "removal_s": t, "wall_s": float(wall), "peak_mb": int(rss) // 1024,
               "updates": s["dexel_updates"], "volume": s["removed_volume_mm3"]},
              open(f"{out}/{name}_{r}.json", "w"))
    line.append(f"{name} {s['dexel_updates']} updates in {t:.2f} s = {rate:.1f} M/s (wall {wall} s, peak {int(rss) // 1024} MB)")
a, b = (json.load(open(f"{out}/{n}_{r}.json"))["rate"] for n in ("impeller", "adaptive"))
print(f"round {r}: " + "; ".join(line) + f"; ratio {a / b:.3f}")
PY
done
python3 - "$out" "$rounds" <<'PY'
import json, statistics, sys
out, n = sys.argv[1], int(sys.argv[2])
get = lambda name: [json.load(open(f"{out}/{name}_{r}.json"))["rate"] for r in range(1, n + 1)]
imp, ad = get("impeller"), get("adaptive")
ratios = [a / b for a, b in zip(imp, ad)]
print(f"median impeller {statistics.median(imp):.1f} M/s, adaptive {statistics.median(ad):.1f} M/s; "
      f"ratio of medians {statistics.median(imp) / statistics.median(ad):.3f}, median ratio {statistics.median(ratios):.3f}, "
      f"rounds at or above 0.5: {sum(x >= 0.5 for x in ratios)} of {n}")
PY
