#!/usr/bin/env bash
# Peak RSS (VmHWM) of an API process (`millsim serve --workers 0`) and a worker process
# (`millsim worker --workers 1`) for one simulate job whose exported stock is large: a
# ball-end raster over a ramp on a 100 x 40 x 10 mm block, whose surface changes height
# from cell to cell (cell 0.03 mm: a 54 MB STL). The job runs, its stock is downloaded,
# then both processes' VmHWM are printed (README, "Scaling out": produced files).
#
#   scripts/produced-file-rss.sh MILLSIM_BIN CELL_MM [DATABASE_URL]
#
# DATABASE_URL defaults to a SQLite file in a temporary folder (removed after).
set -eu
bin=$1; cell=$2
dir=$(mktemp -d)
db=${3:-sqlite://$dir/t.db}
trap 'kill $api $worker 2>/dev/null || true; rm -rf "$dir"' EXIT
python3 - "$dir/raster.nc" <<'PY'
import sys
lines = ["G21 G90 G17", "S10000 M3", "G0 Z5", "G0 X-10 Y-20", "G1 Z-1 F2000"]
for i in range(58):
    y = -20.0 + 0.7 * i
    lines.append(f"G1 X110 Y{y:.3f} Z-4 F4000" if i % 2 == 0 else f"G1 X-10 Y{y:.3f} Z-1 F4000")
    lines.append(f"G1 Y{y + 0.7:.3f}")
lines += ["G0 Z5", "M30"]
open(sys.argv[1], "w").write("\n".join(lines) + "\n")
PY
"$bin" serve --bind 127.0.0.1:0 --database "$db" --workers 0 --job-memory-mb 6000 >"$dir/api.out" 2>"$dir/api.err" &
api=$!
for _ in $(seq 100); do grep -q listening "$dir/api.out" 2>/dev/null && break; sleep 0.1; done
base=$(sed -n 's/^millsim listening on //p' "$dir/api.out")
"$bin" worker --database "$db" --workers 1 --job-memory-mb 6000 2>"$dir/worker.err" &
worker=$!
post() { curl -sf -X POST "$base$1" -H "content-type: $2" --data-binary "$3" | jq -r .id; }
stock=$(post /v1/stocks application/json '{"kind":"block","min":[0,-20,-10],"max":[100,20,0]}')
tool=$(post /v1/tools application/json '{"type":"ball","diameter_mm":10,"flutes":2,"helix_deg":30,"flute_length_mm":20}')
prog=$(post "/v1/programs?name=raster.nc" text/plain "@$dir/raster.nc")
job=$(post /v1/jobs application/json "{\"kind\":\"simulate\",\"inputs\":{\"program\":\"$prog\",\"stock\":\"$stock\",\"tool\":\"$tool\"},\"options\":{\"material\":\"Al7075-T6\",\"cell_mm\":$cell}}")
start=$(date +%s)
while :; do
  status=$(curl -sf "$base/v1/jobs/$job" | jq -r .status)
  [ "$status" = queued ] || [ "$status" = running ] || break
  sleep 0.5
done
echo "job $job: $status after $(( $(date +%s) - start )) s; memory estimate $(curl -sf "$base/v1/jobs/$job" | jq -c .summary.memory.estimate_mb) MB"
curl -sf -o "$dir/stock.stl" -w 'stock.stl: %{size_download} bytes in %{time_total} s\n' "$base/v1/jobs/$job/stock.stl"
echo "api    $(grep VmHWM /proc/$api/status)"
echo "worker $(grep VmHWM /proc/$worker/status)"
