#!/usr/bin/env bash
# What the unseen-space pass costs the live node: `ist_monitor node` with the embedded demo config
# and `-p unobserved:=MODE`, the bundled demo bag played into it (`ist_monitor play bags/demo
# --loops 3`), the answers measured on ~/link_distances (the seen outputs, which go before the
# pass) and, with the pass on, on ~/unseen_link_distances (the frame's last word, after it). The
# modes protect (the demo config's), report (the node's default) and ignore, alternated --rounds
# times in one run; one line per measurement: answered of published, latency p50 / p99 / max.
#
#   ../shared/tools/netns-run tools/unseen_latency.sh [--rounds 5]
#
# Needs target/release/ist_monitor (cargo build --release). DDS discovers by multicast: it
# refuses to run outside a private network namespace that has only loopback.
set -euo pipefail
cd "$(dirname "$0")/.."
rounds=5
while [ $# -gt 0 ]; do
  case $1 in
    --rounds) rounds=$2; shift 2 ;;
    *) echo "unseen_latency.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
source tools/lib/private_network.sh
require_private_network unseen_latency.sh
bin=$PWD/target/release/ist_monitor
logs=$(mktemp -d)
trap 'rm -rf "$logs"' EXIT
for round in $(seq 1 "$rounds"); do
  for mode in protect report ignore; do
    log=$logs/node_${mode}_$round.log
    "$bin" node --ros-args -p "unobserved:=$mode" > "$log" 2>&1 &
    node=$!
    for _ in $(seq 1 120); do
      grep -q "up: node" "$log" && break
      sleep 0.5
    done
    sleep 1
    topics=/ist_monitor/link_distances
    [ "$mode" != ignore ] && topics="$topics /ist_monitor/unseen_link_distances"
    for topic in $topics; do
      summary=$("$bin" play bags/demo --loops 3 --measure "$topic" 2>/dev/null | tail -1)
      echo "round $round unobserved:=$mode $topic: $summary"
    done
    kill -INT "$node"
    wait "$node" 2>/dev/null || true
  done
done
