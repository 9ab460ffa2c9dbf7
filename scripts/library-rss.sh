#!/usr/bin/env bash
# A large Fusion 360 tool library against an API process (`millsim serve --workers 0`, under
# /usr/bin/time -v): the upload's time and peak RSS, then three concurrent GETs of it, each
# one's time and the peak RSS they add (README, "Tool libraries"; issue 34 item 2).
#
#   scripts/library-rss.sh MILLSIM_BIN [TOOLS [FIELDS [DATABASE_URL]]]
#
# The library has TOOLS flat end mills (default 10,000) with FIELDS geometry fields millsim
# does not model (default 700): about 60 MB. DATABASE_URL defaults to a SQLite file in a
# temporary folder (removed after). The peaks are VmHWM, reset before each phase
# (/proc/PID/clear_refs, which resets /usr/bin/time's maximum too: its last line is the
# GETs' phase).
set -eu
bin=$1; tools=${2:-10000}; fields=${3:-700}
dir=$(mktemp -d)
db=${4:-sqlite://$dir/t.db}
trap 'kill $timer 2>/dev/null || true; rm -rf "$dir"' EXIT
python3 - "$dir/lib.json" "$tools" "$fields" <<'PY'
import sys
path, tools, fields = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
unknown = ",".join(f'"x{k}":1' for k in range(fields))
with open(path, "w") as f:
    f.write('{"data":[')
    for n in range(1, tools + 1):
        if n > 1:
            f.write(",")
        f.write('{"type":"flat end mill","unit":"millimeters","geometry":{"DC":6,"NOF":3,"LCF":18,%s},"post-process":{"number":%d}}' % (unknown, n))
    f.write("]}")
PY
echo "library: $tools tools x $fields unknown fields, $(stat -c %s "$dir/lib.json") bytes"
/usr/bin/time -v -o "$dir/time" "$bin" serve --bind 127.0.0.1:0 --database "$db" --workers 0 \
  --max-program-bytes 200000000 >"$dir/api.out" 2>"$dir/api.err" &
timer=$!
for _ in $(seq 100); do grep -q listening "$dir/api.out" 2>/dev/null && break; sleep 0.1; done
base=$(sed -n 's/^millsim listening on //p' "$dir/api.out")
api=$(pgrep -P "$timer")
hwm() { grep VmHWM "/proc/$api/status" | awk '{printf "%.0f MB", $2/1024}'; }
rss() { grep VmRSS "/proc/$api/status" | awk '{printf "%.0f MB", $2/1024}'; }
echo "before the upload: RSS $(rss)"
echo 5 >"/proc/$api/clear_refs"
up=$(curl -sS -X POST "$base/v1/tool-libraries?name=big.json" --data-binary "@$dir/lib.json" \
  -o "$dir/up.json" -w 'HTTP %{http_code} in %{time_total} s')
echo "upload: $up, peak RSS $(hwm)"
id=$(jq -r .id "$dir/up.json")
echo "before the GETs: RSS $(rss)"
echo 5 >"/proc/$api/clear_refs"
pids=()
for i in 1 2 3; do
  curl -sS -o "$dir/get$i.json" -w "GET $i: HTTP %{http_code}, %{size_download} bytes in %{time_total} s\n" \
    "$base/v1/tool-libraries/$id" &
  pids+=($!)
done
wait "${pids[@]}" || true
echo "3 concurrent GETs: peak RSS $(hwm) (VmHWM reset before them)"
kill "$api"
wait "$timer" || true
grep "Maximum resident" "$dir/time"
