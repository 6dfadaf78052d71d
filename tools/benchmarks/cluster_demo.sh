#!/usr/bin/env bash
# A real Dask cluster on one machine: `dask scheduler` on this host and one `dask worker` in each of two network
# namespaces (each its own host: its own interface and address, reached over a veth pair), `dynid fit --scheduler`
# from this host, and a worker killed in the middle of the fit (docs/deployment.md#many-runs-on-a-dask-cluster).
#
#   tools/benchmarks/cluster_demo.sh RUN [RUN ...]        (as root: ip netns; the runs at paths every worker reads)
#
# Addresses: 10.233.0.0/24 inside namespaces this script makes and deletes (nothing leaves the machine).
# Everything it starts is stopped at the end, by process id. Logs in $OUT (default a temporary directory).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
bin=$root/.venv/bin
OUT=${OUT:-$(mktemp -d /tmp/dynid-cluster.XXXX)}
((EUID == 0)) || { echo "cluster_demo: needs root (ip netns)" >&2; exit 2; }
(($#)) || { echo "usage: $0 RUN [RUN ...]" >&2; exit 2; }
data=(); for r in "$@"; do data+=(--data "$(realpath "$r")"); done

pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    sleep 1
    for n in 1 2; do ip netns del "dynw$n" 2>/dev/null || true; ip link del "dynh$n" 2>/dev/null || true; done
}
trap cleanup EXIT

# Two "hosts": namespace dynwN with 10.233.0.(N+1)/32, this host's end 10.233.0.1 on dynhN.
for n in 1 2; do
    ip netns add "dynw$n"
    ip link add "dynh$n" type veth peer name eth0 netns "dynw$n"
    ip addr add 10.233.0.1/32 dev "dynh$n" 2>/dev/null || true
    ip link set "dynh$n" up
    ip route add "10.233.0.$((n + 1))/32" dev "dynh$n"
    ip netns exec "dynw$n" ip addr add "10.233.0.$((n + 1))/32" dev eth0
    ip netns exec "dynw$n" ip link set lo up
    ip netns exec "dynw$n" ip link set eth0 up
    ip netns exec "dynw$n" ip route add 10.233.0.1/32 dev eth0
    ip netns exec "dynw$n" ip route add default via 10.233.0.1 dev eth0 onlink
done

export DASK_DISTRIBUTED__WORKER__DAEMON=False
# Without it, tasks wait for workers forever (the default): a fit whose every worker died would hang (step 3)
DASK_DISTRIBUTED__SCHEDULER__NO_WORKERS_TIMEOUT=30s \
"$bin/dask" scheduler --host 10.233.0.1 --port 8786 --no-dashboard >"$OUT/scheduler.log" 2>&1 &
pids+=($!)
sleep 4
for n in 1 2; do
    ip netns exec "dynw$n" "$bin/dask" worker tcp://10.233.0.1:8786 --host "10.233.0.$((n + 1))" \
        --nworkers 1 --nthreads 1 --no-dashboard --name "host$n" >"$OUT/worker$n.log" 2>&1 &
    pids+=($!)
done
sleep 8
echo "== the cluster"
"$bin/python" - <<'EOF'
from distributed import Client
c = Client("tcp://10.233.0.1:8786", timeout=10)
for addr, w in c.scheduler_info()["workers"].items():
    print(f"  {w['name']}: {addr}, {w['nthreads']} thread")
c.close()
EOF

echo "== 1. the fit on the cluster"
/usr/bin/time -f "  %e s" "$bin/dynid" fit "${data[@]}" --scheduler tcp://10.233.0.1:8786 --out "$OUT/cluster.json" \
    2>&1 | sed -n '1,2p;$p'

# started FILE: wait until the fit writing FILE has connected to the cluster (its first line), then 5 s more
started() { for _ in $(seq 300); do grep -q "^fitting" "$1" 2>/dev/null && break; sleep 1; done; sleep 5; }

echo "== 2. the same fit, host1's worker process killed (SIGKILL) 5 s after the fit connected; its nanny restarts it"
"$bin/dynid" fit "${data[@]}" --scheduler tcp://10.233.0.1:8786 --out "$OUT/killed.json" >"$OUT/killed.txt" 2>&1 &
fit=$!
pids+=($fit)
started "$OUT/killed.txt"
victim=$(ip netns pids dynw1 | while read -r p; do
    if tr '\0' ' ' <"/proc/$p/cmdline" | grep -q "spawn_main"; then echo "$p"; fi; done | head -1)
echo "  killing worker process $victim in dynw1"
kill -9 "$victim"
set +e; wait "$fit"; code=$?; set -e
echo "  exit $code"; sed -n '1,2p' "$OUT/killed.txt"
"$bin/python" - "$OUT/cluster.json" "$OUT/killed.json" <<'EOF'
import json, sys
import numpy as np
try:
    a, b = (np.array(list(json.load(open(p))["parameters"].values())) for p in sys.argv[1:3])
    print(f"  largest relative difference from fit 1: {np.max(np.abs(a - b) / np.maximum(np.abs(a), 1e-12)):.1e}")
except FileNotFoundError as e:
    print(f"  no model: {e.filename}")
EOF
grep -h -i -E "restart|lost|died|closed|removing worker" "$OUT"/scheduler.log "$OUT"/worker1.log | sed 's/^/  log: /' | head -8

echo "== 3. both workers' hosts stopped (every dask process in both namespaces killed) 5 s after a fit connected"
"$bin/dynid" fit "${data[@]}" --scheduler tcp://10.233.0.1:8786 --out "$OUT/dead.json" >"$OUT/dead.txt" 2>&1 &
fit=$!
pids+=($fit)
started "$OUT/dead.txt"
for n in 1 2; do ip netns pids "dynw$n" | xargs -r kill -9; done
echo "  both hosts' workers killed; waiting up to 120 s for the fit (the scheduler's no-workers-timeout: 30 s)"
for _ in $(seq 120); do kill -0 "$fit" 2>/dev/null || break; sleep 1; done
if kill -0 "$fit" 2>/dev/null; then
    echo "  the fit still waits after 120 s"
    kill -TERM "$fit"; set +e; wait "$fit"; code=$?; set -e; echo "  terminated: exit $code"
else
    set +e; wait "$fit"; code=$?; set -e; echo "  exit $code"
fi
tail -2 "$OUT/dead.txt" | sed 's/^/  /'
echo "logs: $OUT"
