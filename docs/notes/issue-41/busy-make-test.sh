#!/usr/bin/env bash
# make test from a clean clone with 8 busy loops beside it (issue 41's check)
cd /tmp/ciclone_busy
pids=()
for i in $(seq 8); do ( while :; do :; done ) & pids+=($!); done
( while :; do echo "$(date +%T) $(cut -d' ' -f1-3 /proc/loadavg)"; sleep 30; done ) > /work/notes/busy/load.log &
mon=$!
start=$(date +%s)
PYTEST_ADDOPTS="-v" .ci/run > /work/notes/busy/ci.log 2>&1
rc=$?
end=$(date +%s)
kill "${pids[@]}" $mon
echo "rc=$rc wall_s=$((end-start)) busy_loops=8 commit=$(git rev-parse --short HEAD)" > /work/notes/busy/result.txt
