#!/usr/bin/env bash
# What docker-compose.yml runs, without Docker: one API and N worker processes against one
# PostgreSQL database (README, "Scaling out"). Stops them all on Ctrl-C / SIGTERM (workers
# get their shutdown grace; unfinished jobs go back to the queue).
#
#   scripts/scale-out.sh DATABASE_URL [WORKERS] [BIND]
#
# WORKERS: worker processes (default 2), each with MILLSIM_WORKERS engine threads (default
# its cores); BIND: the API's address (default 127.0.0.1:8080). MILLSIM_BIN names the
# binary (default: target/release/millsim, else millsim on PATH). Other MILLSIM_*
# variables (MILLSIM_API_KEY_FILE, ...) reach every process. With Debian's postgresql, a
# throwaway cluster for a try:
#
#   pg_virtualenv bash -c 'scripts/scale-out.sh "postgres://$PGUSER:$PGPASSWORD@127.0.0.1:$PGPORT/postgres" 4'
set -eu

url=${1:?usage: scale-out.sh DATABASE_URL [WORKERS] [BIND]}
workers=${2:-2}
bind=${3:-127.0.0.1:8080}
here=$(dirname "$0")
bin=${MILLSIM_BIN:-}
if [ -z "$bin" ]; then
  if [ -x "$here/../target/release/millsim" ]; then bin="$here/../target/release/millsim"; else bin=millsim; fi
fi

pids=""
stop() {
  trap - INT TERM EXIT
  # SIGTERM: each process finishes or gives back its running jobs, then exits.
  for p in $pids; do kill -TERM "$p" 2>/dev/null || true; done
  for p in $pids; do wait "$p" 2>/dev/null || true; done
}
trap stop INT TERM EXIT

# The API first: it migrates the database (the workers would wait for its lock anyway).
"$bin" serve --database "$url" --workers 0 --bind "$bind" &
pids="$!"
i=0
while [ "$i" -lt "$workers" ]; do
  "$bin" worker --database "$url" &
  pids="$pids $!"
  i=$((i + 1))
done
echo "scale-out: API on http://$bind (pid ${pids%% *}), $workers worker processes (pids ${pids#* })" >&2
# Until one of them stops (or we are told to), then stop the rest.
wait -n
